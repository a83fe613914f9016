# Set-up and entry points. Everything runs inside .venv, created on first use.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# the install builds the compiled kernels (setup.py: every slitcli/**/*.pyx) into the
# clone, so it is redone when one of their sources changes
KERNEL_SOURCES := $(shell find slitcli -name '*.pyx' -o -name '*.pxd' 2>/dev/null)

.PHONY: venv reproduce-figures test bench lint clean

$(STAMP): pyproject.toml setup.py $(KERNEL_SOURCES)
	@echo "set-up: installing slitcli and its dependencies into $(VENV), building its kernels"
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	@# the sources' bytecode: Python would not write it where PYTHONDONTWRITEBYTECODE is
	@# set (many CI images), and every start would compile them again
	$(PY) -m compileall -q slitcli
	touch $(STAMP)

venv: $(STAMP)

reproduce-figures: $(STAMP)
	$(PY) -m slitcli.reproduce

# the suite on every core (at most 4 workers: its tests are single-threaded, and each
# worker holds its own module fixtures); `pytest tests/x.py` alone stays serial
test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/pytest -n auto --maxprocesses 4

bench: $(STAMP)
	$(PY) bench/run.py

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf out bench/results.json .pytest_cache .ruff_cache
