# Isochor developer tasks.  `make run` starts the editor, `make test` runs the tests.
VENV   := .venv
PY     := $(VENV)/bin/python
PYTHON ?= python3
# Blender's bpy (numpy < 2, as Blender ships) in a venv of its own, for the add-on's tests
BVENV  := .venv-blender
BPY    := $(BVENV)/bin/python
# bpy alone (what Blender ships: its Python and numpy), where the add-on's tests install the
# built extension as a user does
BONLY  := .venv-bpy
# the Khronos glTF validator (npm gltf-validator) the glTF tests run
JSDEPS := tests/js/node_modules/.installed

.PHONY: venv testdeps sysdeps run test test-numpy test-blender lint docs bench assets addon clean

# Debian system packages (Qt/VTK runtime libs, Xvfb); apt runs only if something is missing.
sysdeps:
	@bash .ci/sysdeps

# the library with the editor (the gui extra), the tests and the compiled kernels; `make test`
# adds the Blender venv and the glTF validator
venv: $(VENV)/.installed

testdeps: $(BVENV)/.installed $(BONLY)/.installed $(JSDEPS)

$(PY):
	$(PYTHON) -m venv $(VENV)

# Re-install only when pyproject.toml (dependencies, the package-dir mapping) or the version
# in isochor/__init__.py is newer than the stamp. setuptools and wheel let the tests build
# a wheel without network. Then the optional kernels are compiled into the user's cache
# (else the first run compiles them in the background; a failure leaves the NumPy path).
$(VENV)/.installed: pyproject.toml isochor/__init__.py | $(PY)
	$(PY) -m pip install --upgrade pip 'setuptools>=77' wheel
	$(PY) -m pip install -e '.[gui,test,bench,fast]'
	-$(PY) -m isochor.core.kernels --compile
	touch $@

# bpy has a wheel for Python 3.11 only: elsewhere the Blender tests skip, saying why.
$(BVENV)/.installed: pyproject.toml isochor/__init__.py
	@if $(PYTHON) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then \
	  $(PYTHON) -m venv $(BVENV) && \
	  $(BPY) -m pip install --upgrade pip 'setuptools>=77' wheel && \
	  $(BPY) -m pip install -e '.[gui,test,blender]' && touch $@; \
	else echo "venv: bpy needs Python 3.11; the Blender tests will skip"; fi

$(BONLY)/.installed: pyproject.toml
	@if $(PYTHON) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then \
	  $(PYTHON) -m venv $(BONLY) && $(BONLY)/bin/python -m pip install -q 'bpy==5.0.1' && \
	  touch $@; \
	else echo "venv: bpy needs Python 3.11; the extension's install test will skip"; fi

$(JSDEPS): tests/js/package.json tests/js/package-lock.json
	@if command -v npm >/dev/null; then \
	  cd tests/js && npm ci --no-audit --no-fund && touch node_modules/.installed; \
	else echo "venv: no npm; the glTF validator tests will skip (CI installs it)"; fi

run: sysdeps venv
	$(VENV)/bin/isochor $(ARGS)

# every test: the suite in .venv, then the add-on's in .venv-blender (skipped, saying why,
# where bpy could not be installed)
test: sysdeps venv testdeps
	$(PY) -m pytest -q $(ARGS)
	@if [ -f $(BVENV)/.installed ]; then $(MAKE) --no-print-directory test-blender; \
	else echo "test: no .venv-blender (bpy needs Python 3.11): the Blender tests skipped"; fi

# the add-on and Blender round-trip tests, in the venv with bpy
test-blender: testdeps
	$(BPY) -m pytest -q -p no:xvfb tests/test_blender.py $(ARGS)

# the Blender extension (add-on) packages: dist/isochor-VERSION-PLATFORM.zip, one per
# platform with its wheels (ARGS=--platform=current: this one only)
addon: testdeps
	$(BPY) blender/build.py $(ARGS)

# the core and API tests on the NumPy path (what an install without numba runs): the
# compiled kernels switched off, the GUI tests left out
test-numpy: venv
	ISOCHOR_NO_JIT=1 $(PY) -m pytest -q --ignore=tests/gui $(ARGS)

# the same lint CI runs: ruff, then mypy and the import contracts (import-linter) on the
# package laid out as it installs (tests/lint.py)
lint: venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(PY) -m tests.lint

# the API reference, from the docstrings and docs/*.md (Sphinx with the docs extra):
# build/docs/index.html; warnings are errors, as in CI
docs: $(VENV)/.docs
	$(VENV)/bin/sphinx-build -W --keep-going -q -E -b html docs build/docs
	@echo "docs: build/docs/index.html"

$(VENV)/.docs: $(VENV)/.installed
	$(PY) -m pip install -e '.[docs]'
	touch $@

# regenerate the shipped sample models, example scenarios and icon (assets/)
assets: venv
	$(PY) assets/make_assets.py

# the window's rows of the benchmark need a display: a virtual one where there is none
XVFB := $(if $(DISPLAY),,$(shell command -v xvfb-run >/dev/null 2>&1 && echo xvfb-run -a))

bench: sysdeps venv
	$(XVFB) $(PY) -m benchmarks $(ARGS)

clean:
	rm -rf $(VENV) $(BVENV) $(BONLY) tests/js/node_modules build dist *.egg-info .pytest_cache out
