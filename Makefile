# swarmloc: `make demo` runs a 5-vehicle swarm, `make test` runs the suite. Both set up .venv first.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# the suite runs in two pytest-xdist workers, a test file per worker at a time (module fixtures run once),
# in collection order: the long files first (tests/conftest.py); PARALLEL= runs it in one process
PARALLEL ?= -n 2 --dist loadfile --no-loadscope-reorder

.PHONY: demo test unit integration fuzz test-docker bench soak docs viewer-check clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/swarm up --vehicles 5 --duration 60 --mode lockstep --seed 1 --out runs --name demo

test: $(STAMP)
	$(BIN)/python -m pytest -q $(PARALLEL)

unit: $(STAMP)
	$(BIN)/python -m pytest -q $(PARALLEL) tests/unit

integration: $(STAMP)
	$(BIN)/python -m pytest -q $(PARALLEL) tests/integration

fuzz: $(STAMP)
	$(BIN)/python -m pytest -q tests/unit/bus --hypothesis-profile=fuzz-long -k "garbage or mutated or arbitrary or wrong_values or claim_decoders"

test-docker: $(STAMP)
	$(BIN)/python -m pytest -q -m docker tests/docker

bench: $(STAMP)
	$(BIN)/python -m bench.run_all

soak: $(STAMP)
	$(BIN)/python -m bench.soak

# opens the live view and run.mcap in a Lichtblick web build (LICHTBLICK=.../web/.webpack) in headless
# Chromium and fails on any alert or empty plot series (docs/live-view.md); not part of make test
viewer-check: $(STAMP)
	$(BIN)/python tools/viewer_check.py --lichtblick "$(LICHTBLICK)"

docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

clean:
	rm -rf $(VENV) runs site .pytest_cache .hypothesis
