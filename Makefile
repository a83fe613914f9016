# Set-up and entry points. Everything runs inside .venv, created on first use.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# numba kernels compiled for this machine (slitcli warm-up, docs/install.md); redone when
# a file with kernels or with what kernels inline (@njit, @intrinsic, @register_jitable,
# @overload) changes. numba keys a cache entry on its own file's modification time only,
# so a changed intrinsic would leave its callers' entries stale: every entry goes first
KERNELS := $(VENV)/.kernels
# the Cython kernels (setup.py), built into the clone by the editable install and again
# (in place, without a fresh build environment) when a .pyx or .pxd changes
EXTENSIONS := $(VENV)/.extensions
EXTENSION_SOURCES := $(shell find slitcli -name '*.pyx' -o -name '*.pxd' 2>/dev/null)
KERNEL_SOURCES := $(shell grep -rlE --include='*.py' \
	'^\s*@(\w+\.)?(n?jit|intrinsic|register_jitable|overload)\b' slitcli 2>/dev/null)

.PHONY: venv reproduce-figures test bench lint clean

$(STAMP): pyproject.toml setup.py
	@echo "set-up: installing slitcli and its dependencies into $(VENV) (a few minutes)"
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP) $(EXTENSIONS)

$(EXTENSIONS): $(STAMP) $(EXTENSION_SOURCES)
	@echo "set-up: building the compiled kernels (Cython and the C compiler)"
	$(PY) -m pip install --quiet --no-build-isolation --no-deps -e .
	touch $(EXTENSIONS)

$(KERNELS): $(EXTENSIONS) $(KERNEL_SOURCES)
	@echo "set-up: compiling the numba kernels for this machine (one line per job)"
	$(if $(filter slitcli/%,$?),find slitcli -name '*.nbi' -delete -o -name '*.nbc' -delete)
	$(VENV)/bin/slitcli warm-up
	touch $(KERNELS)

venv: $(KERNELS)

reproduce-figures: $(KERNELS)
	$(PY) -m slitcli.reproduce

# the suite on every core (at most 4 workers: its tests are single-threaded, and each
# worker holds its own module fixtures); `pytest tests/x.py` alone stays serial
test: $(KERNELS)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/pytest -n auto --maxprocesses 4

bench: $(KERNELS)
	$(PY) bench/run.py

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf out bench/results.json .pytest_cache .ruff_cache
