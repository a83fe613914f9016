# Set-up and entry points. Everything runs inside .venv, created on first use.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# the Cython kernels (setup.py), built into the clone by the editable install and again
# (in place, without a fresh build environment) when a .pyx or .pxd changes; the sources'
# bytecode is written then too (Python would not where PYTHONDONTWRITEBYTECODE is set,
# as in many CI images, and every start would compile them again)
EXTENSIONS := $(VENV)/.extensions
EXTENSION_SOURCES := $(shell find slitcli -name '*.pyx' -o -name '*.pxd' 2>/dev/null)

.PHONY: venv reproduce-figures test bench lint clean

$(STAMP): pyproject.toml setup.py
	@echo "set-up: installing slitcli and its dependencies into $(VENV) (a few minutes)"
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	$(PY) -m compileall -q slitcli
	touch $(STAMP) $(EXTENSIONS)

$(EXTENSIONS): $(STAMP) $(EXTENSION_SOURCES)
	@echo "set-up: building the compiled kernels (Cython and the C compiler)"
	$(PY) -m pip install --quiet --no-build-isolation --no-deps -e .
	$(PY) -m compileall -q slitcli
	touch $(EXTENSIONS)

venv: $(EXTENSIONS)

reproduce-figures: $(EXTENSIONS)
	$(PY) -m slitcli.reproduce

# the suite on every core (at most 4 workers: its tests are single-threaded, and each
# worker holds its own module fixtures); `pytest tests/x.py` alone stays serial
test: $(EXTENSIONS)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/pytest -n auto --maxprocesses 4

bench: $(EXTENSIONS)
	$(PY) bench/run.py

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf out bench/results.json .pytest_cache .ruff_cache
