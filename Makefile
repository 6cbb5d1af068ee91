# Quick start: `make demo` and `make test` on a fresh clone with Python 3.11 and make.
PYTHON ?= python3.11
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-test
DEMO_OUT ?= demo-output

.PHONY: demo test lint bench clean clean-kernels

$(BIN)/python:
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "make: $(PYTHON) not found; run 'make PYTHON=python3 ...'" >&2; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[test]"
	@touch $(STAMP)

demo: $(STAMP)
	$(BIN)/torquemod demo --out $(DEMO_OUT) --force

# The suite on every core (at most 4), a test file's tests on one worker (its module
# fixtures built once). `$(BIN)/python -m pytest` runs it in one process.
test: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/python -m pytest -q -n auto --maxprocesses 4 --dist loadfile

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

bench: $(STAMP)
	$(BIN)/python benchmarks/phase_accuracy.py
	$(BIN)/python benchmarks/throughput.py
	$(BIN)/python benchmarks/simulate.py

# numba's disk cache checks only a kernel's own source file: after editing a kernel that
# others call (in another module), drop the compiled copies so that every caller recompiles.
clean-kernels:
	find src -path '*/__pycache__/*' \( -name '*.nbi' -o -name '*.nbc' \) -delete

clean: clean-kernels
	rm -rf $(VENV) $(DEMO_OUT) build *.egg-info src/*.egg-info .pytest_cache
