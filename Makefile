# brdfcorr developer commands. `make demo` and `make test` work from a fresh clone.
#
# Both install exact versions from the lock files in requirements/ (made by `make lock` from the
# version ranges in pyproject.toml), so a new release upstream cannot change what a fresh clone
# runs. `make test-latest` runs the suite against the newest releases instead (not part of CI).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# pytest-xdist workers: one per core (`make test WORKERS=1` runs the suite in one process).
WORKERS ?= auto
# The version of uv that makes the lock files (`make lock` only; installing needs pip alone).
UV_VERSION := 0.13.9
LOCK := uv pip compile --quiet --universal --python-version 3.11 --generate-hashes --no-header

.PHONY: demo test lint rewrite-tests lock test-latest clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# Every package with its hash, then brdfcorr itself (editable, built by the locked setuptools).
# The stamps re-run the install when a lock file or pyproject.toml changes.
$(VENV)/.installed: requirements/run.lock pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --require-hashes --no-deps -r requirements/run.lock
	PYTHONWARNINGS=ignore $(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
	touch $@

$(VENV)/.installed-test: requirements/test.lock pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --require-hashes --no-deps -r requirements/test.lock
	PYTHONWARNINGS=ignore $(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
	touch $@ $(VENV)/.installed

demo: $(VENV)/.installed
	$(BIN)/brdfcorr demo --output-dir demo_output

# Lint (ruff: pyflakes, pycodestyle, import order, complexity <= 15), type-check the core
# packages (mypy; the file list is in pyproject.toml) and check the layers and that no modules
# import each other in a circle (import-linter; the contracts are in pyproject.toml) before the tests.
lint: $(VENV)/.installed-test
	$(BIN)/ruff check brdfcorr tests benchmarks examples
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

# Lint on one core while the tests are made ready on the other (mypy runs on one), then the tests.
test: $(VENV)/.installed-test
	$(MAKE) --no-print-directory -j2 lint rewrite-tests
	$(BIN)/python -m pytest -n $(WORKERS)

# The package's bytecode, and the test modules as pytest rewrites their asserts, written once
# before the run. Where PYTHONDONTWRITEBYTECODE is set, every brdfcorr process the tests start
# (the docs' commands, the command-line tests) would compile the package again, and each pytest
# worker would rewrite every test module again (5 s of each worker's start on two cores). A
# collection that fails here is reported by the run that follows.
rewrite-tests: $(VENV)/.installed-test
	$(BIN)/python -m compileall -q brdfcorr
	-PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest --collect-only -q -p no:cacheprovider > /dev/null

# Refresh both lock files from pyproject.toml's ranges; the run lock takes the test lock's
# versions, so `make demo` and `make test` install the same brdfcorr dependencies. The run lock
# holds the hdf5 extra, so every example runs after `make demo` (NEON and EMIT products).
lock:
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet uv==$(UV_VERSION)
	.venv-lock/bin/$(LOCK) pyproject.toml requirements/build.in --extra test -o requirements/test.lock
	.venv-lock/bin/$(LOCK) pyproject.toml requirements/build.in --extra hdf5 -c requirements/test.lock -o requirements/run.lock

# The suite against the newest releases of every dependency, in a separate environment.
test-latest:
	$(PYTHON) -m venv .venv-latest
	.venv-latest/bin/python -m pip install --quiet --upgrade pip
	.venv-latest/bin/python -m pip install --quiet --upgrade -e '.[test]'
	.venv-latest/bin/python -m pytest -n $(WORKERS)

clean:
	rm -rf $(VENV) .venv-latest .venv-lock demo_output .pytest_cache .hypothesis
