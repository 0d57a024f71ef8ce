# Isochor developer tasks.  `make run` starts the editor, `make test` runs the tests.
VENV   := .venv
PY     := $(VENV)/bin/python
PYTHON ?= python3

.PHONY: venv sysdeps run test test-numpy lint bench assets clean

# Debian system packages (Qt/VTK runtime libs, Xvfb); apt runs only if something is missing.
sysdeps:
	@bash .ci/sysdeps

venv: $(VENV)/.installed

$(PY):
	$(PYTHON) -m venv $(VENV)

# Re-install only when pyproject.toml (dependencies, the package-dir mapping) or the version
# in isochor/__init__.py is newer than the stamp. setuptools and wheel let the tests build
# a wheel without network. Then the optional kernels are compiled into the user's cache
# (else the first run compiles them in the background; a failure leaves the NumPy path).
$(VENV)/.installed: pyproject.toml isochor/__init__.py | $(PY)
	$(PY) -m pip install --upgrade pip 'setuptools>=68' wheel
	$(PY) -m pip install -e '.[test,bench,fast]'
	-$(PY) -m isochor.core.kernels --compile
	touch $@

run: sysdeps venv
	$(VENV)/bin/isochor $(ARGS)

test: sysdeps venv
	$(PY) -m pytest -q $(ARGS)

# the core and API tests on the NumPy path (what an install without numba runs): the
# compiled kernels switched off, the GUI tests left out
test-numpy: venv
	ISOCHOR_NO_JIT=1 $(PY) -m pytest -q --ignore=tests/gui $(ARGS)

# the same lint CI runs
lint: venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

# regenerate the shipped sample models, example scenarios and icon (assets/)
assets: venv
	$(PY) assets/make_assets.py

# the window's rows of the benchmark need a display: a virtual one where there is none
XVFB := $(if $(DISPLAY),,$(shell command -v xvfb-run >/dev/null 2>&1 && echo xvfb-run -a))

bench: sysdeps venv
	$(XVFB) $(PY) -m benchmarks $(ARGS)

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache out
