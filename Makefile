# hnnbench: `make benchmark` runs the whole benchmark, `make test` runs the tests.
# Both set up .venv first (scripts/setup.sh; idempotent).
SHELL := /bin/bash
VENV := .venv/bin
# The measured-pendulum data: $HNNBENCH_DATA_DIR, else ../shared/... beside the clone.
export HNNBENCH_DATA_DIR ?= $(abspath ../shared/data/schmidt-lipson-2009)
PYTEST_ARGS ?=

.PHONY: setup benchmark quick test test-fast lint ci-sweep clean

setup:
	@scripts/setup.sh

benchmark: setup
	$(VENV)/hnnbench -m system=all model=all

quick: setup
	$(VENV)/hnnbench -m system=all model=all profile=quick

test: setup
	$(VENV)/ruff check .
	$(VENV)/python -m pytest $(PYTEST_ARGS)

test-fast: setup
	$(VENV)/python -m pytest -m "not slow" $(PYTEST_ARGS)

lint: setup
	$(VENV)/ruff check .

clean:
	rm -rf .venv build dist *.egg-info .pytest_cache .ruff_cache
