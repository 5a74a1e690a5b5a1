# Two commands on a fresh machine: `make reproduce` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
SEED ?= 13

.PHONY: reproduce test test-fast lint docs install install-test matrix benchmark clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

## Both install the exact versions that made results/ (constraints.txt); setup.cfg admits the
## range the version matrix proves. The install is editable, so a stamp in the venv stands for it
## until the files that say what to install change (setup.cfg reads the version from keras_rl/__init__.py):
## pip's no-op check costs about 6 s a call. After a pip install by hand, `make -B install-test`.
INSTALLED := $(VENV)/.installed
INSTALLED_TEST := $(VENV)/.installed-test
INSTALL_INPUTS := $(BIN)/python setup.cfg pyproject.toml constraints.txt keras_rl/__init__.py

install: $(INSTALLED)
install-test: $(INSTALLED_TEST)

$(INSTALLED): $(INSTALL_INPUTS)
	$(BIN)/pip install --quiet -c constraints.txt -e .
	touch $@

$(INSTALLED_TEST): $(INSTALL_INPUTS)
	$(BIN)/pip install --quiet -c constraints.txt -e ".[test,torch,ray]"
	touch $@ $(INSTALLED)

## The main reproduction: post 000's faithful DDPG on Pendulum-v1 to EMA > -300. It writes under runs/
## (gitignored), never results/: results/ holds only committed evidence, which the suite reads.
reproduce: install
	$(BIN)/keras-rl reproduce pendulum --variant faithful --seeds $(SEED) --out runs/make-reproduce --overwrite

## The whole suite: lint, then every test (slow training checks included) in two processes.
test: install-test lint
	$(BIN)/python -m pytest -ra --durations=40 -n 2 --dist loadgroup

## The quick tier for day-to-day work (under 2 minutes): no training runs, no Ray, no subprocess CLI runs.
test-fast: install-test lint
	$(BIN)/python -m pytest -ra -m "not slow" -n 2 --dist loadgroup

## ruff (lint and format) and mypy, configured in pyproject.toml: zero findings.
lint: install-test
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

## These pages, built strictly (a broken link or a missing page fails) into site/.
docs: install-test
	$(BIN)/mkdocs build --strict

## The version matrix (matrix/noxfile.py, beside its cell scripts): every cell in its own virtualenv,
## then results/compat/README.md. Hours: one cell is about 20 minutes. A cell resumes where it stopped;
## `nox -f matrix/noxfile.py -s cell-NAME table` runs one.
matrix: $(BIN)/python
	$(BIN)/pip install --quiet -c constraints.txt -e ".[matrix]"
	$(BIN)/nox -f matrix/noxfile.py

benchmark: install
	/usr/bin/time -v $(BIN)/python benchmarks/step_time.py

clean:
	rm -rf $(VENV) build *.egg-info
