# Each target creates .venv if missing and installs the project into it.
PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-$(shell cat pyproject.toml | cksum | cut -d' ' -f1)

.PHONY: demo test test-fast bench bench-evidence lint docs clean

$(BIN)/python:
	@command -v $(PY) >/dev/null 2>&1 || { echo "need $(PY) (or run: make PY=python3 ...)"; exit 1; }
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -q -e ".[test]"
	$(BIN)/imunoise warm-up  # compile every command's numba kernels into numba's cache once
	@rm -f $(VENV)/.installed-*; touch $(STAMP)

demo: $(STAMP)
	$(BIN)/imunoise demo --out out/demo

test: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/python -m pytest -q -p no:cacheprovider --timeout=900 -n auto --maxprocesses=4 --dist loadfile --no-loadscope-reorder

# the suite without the tests marked slow (Monte Carlo, end-to-end runs, the docs build and its examples)
test-fast: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/python -m pytest -q -p no:cacheprovider --timeout=900 -m "not slow" -n 2 --dist loadfile --no-loadscope-reorder

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py --out BENCHMARKS.md

# the long benchmarks left out of `make bench` (benchmarks/run.py OPT_IN): minutes to an hour each
bench-evidence: $(STAMP)
	$(BIN)/python benchmarks/run.py --evidence --out BENCHMARKS-evidence.md
	$(BIN)/python benchmarks/bench_oracle_law.py

docs: $(STAMP)
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs out/docs
	@echo "user guide and API reference: out/docs/index.html"

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

clean:
	rm -rf $(VENV) out build src/*.egg-info
