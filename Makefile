# Two entry points on a fresh machine (see README): `make run` and `make test`.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: run test build native validate bench bench-batch clean

$(BIN)/mast: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

build: $(BIN)/mast
	$(BIN)/mast build

# native FMUs too (compiled C, no Python in the host; needs a C compiler): docs/native.md
native: $(BIN)/mast
	$(BIN)/mast build --native
	$(BIN)/mast validate

validate: build
	$(BIN)/mast validate

# The main job: build the FMUs and the SSP, validate them, run the default co-simulation.
run: validate
	$(BIN)/mast run build/ssp/MAST.ssp --motion z --amplitude 0.01 --frequency 1 --stop-time 3 --out results/z_1Hz

# The suite on every core (pytest-xdist): a test file runs whole on one worker, so its module fixtures (builds,
# shared simulations) are made once, but the diagnoses, whose tests go out one by one (tests/conftest.py, SPREAD);
# `make test PYTEST_WORKERS=0` runs it in this one process.
PYTEST_WORKERS ?= auto
PYTEST_XDIST = -n $(PYTEST_WORKERS) --dist loadfile

test: $(BIN)/mast
	$(BIN)/python -m pytest $(PYTEST_XDIST)

bench: build
	$(BIN)/mast bench

# batch throughput with 1 and 2 workers, per-case overhead, real-time factor (docs/batch.md)
bench-batch: build
	$(BIN)/python benchmarks/batch_throughput.py

clean:
	rm -rf build results .pytest_cache
