# Two commands on a fresh machine: `make reproduce` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
SEED ?= 13

.PHONY: reproduce test test-fast install install-test benchmark clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

install: $(BIN)/python
	$(BIN)/pip install --quiet -e .

install-test: $(BIN)/python
	$(BIN)/pip install --quiet -e ".[test,torch]"

## The main reproduction: post 000's faithful DDPG on Pendulum-v1 to EMA > -300.
reproduce: install
	$(BIN)/keras-rl reproduce pendulum --variant faithful --seeds $(SEED) --out results/make-reproduce --overwrite

## The whole suite, slow threshold tests included.
test: install-test
	$(BIN)/python -m pytest -ra --durations=40

test-fast: install-test
	$(BIN)/python -m pytest -ra -m "not slow"

benchmark: install
	/usr/bin/time -v $(BIN)/python benchmarks/step_time.py

clean:
	rm -rf $(VENV) build *.egg-info
