# One image for every role of a swarm: router, sim, groundstation, vehicle (see docker-compose.yml).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 \
    HOME=/home/swarm MPLCONFIGDIR=/tmp/matplotlib OPENBLAS_NUM_THREADS=1
# the unprivileged user is uid 1000 (numeric, so the image needs no passwd tools)
RUN mkdir -p /runs /secrets /home/swarm && chown 1000:1000 /runs /secrets /home/swarm
WORKDIR /app
COPY pyproject.toml README.md ./
COPY bus ./bus
COPY sim ./sim
COPY vehicle ./vehicle
COPY groundstation ./groundstation
COPY cli ./cli
COPY experiments ./experiments
COPY launch ./launch
COPY deploy ./deploy
RUN pip install --no-compile . && rm -rf /root/.cache

USER 1000:1000
ENTRYPOINT ["swarm"]
CMD ["--help"]
