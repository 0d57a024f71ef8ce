# Isochor developer tasks.  `make run` starts the editor, `make test` runs the tests.
VENV   := .venv
PY     := $(VENV)/bin/python
PYTHON ?= python3

.PHONY: venv sysdeps run test bench clean

# Debian system packages (Qt/VTK runtime libs, Xvfb); apt runs only if something is missing.
sysdeps:
	@bash .ci/sysdeps

venv: $(VENV)/.installed

$(PY):
	$(PYTHON) -m venv $(VENV)

# Re-install only when pyproject.toml (or a package's __init__.py, which decides how the
# editable install maps `core`/`app`) is newer than the stamp.
$(VENV)/.installed: pyproject.toml $(wildcard core/__init__.py app/__init__.py) | $(PY)
	$(PY) -m pip install --upgrade pip
	$(PY) -m pip install -e '.[test,bench]'
	touch $@

run: sysdeps venv
	$(VENV)/bin/isochor $(ARGS)

test: sysdeps venv
	$(PY) -m pytest -q $(ARGS)

bench: sysdeps venv
	$(PY) -m benchmarks $(ARGS)

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache out
