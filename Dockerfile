# One image for every role of a swarm: router, sim, groundstation, vehicle (see docker-compose.yml).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
RUN useradd --create-home --uid 1000 swarm \
 && mkdir -p /runs /secrets \
 && chown swarm:swarm /runs /secrets
WORKDIR /app
COPY pyproject.toml README.md ./
COPY bus ./bus
COPY sim ./sim
COPY vehicle ./vehicle
COPY groundstation ./groundstation
COPY deploy ./deploy
RUN pip install --no-compile . && rm -rf /root/.cache

USER swarm
ENTRYPOINT ["swarm"]
CMD ["--help"]
