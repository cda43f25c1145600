# Every target bootstraps .venv first; re-running is cheap (the stamp file tracks pyproject.toml).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.cpkb-installed

.PHONY: setup demo test test-fast lint format bench clean lock

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	# CPU torch first, so that gpytorch does not pull a CUDA build.
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $(STAMP)

setup: $(STAMP)

demo: setup
	$(BIN)/cpkb demo

test: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/python -m pytest

# The inner loop: everything but the tests marked slow, postgres or browser (see pyproject.toml).
test-fast: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/python -m pytest -m "not slow and not postgres and not browser" -q

# ruff, then mypy over the packages listed in pyproject.toml ([tool.mypy] files).
lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

format: setup
	$(BIN)/ruff check --fix .
	$(BIN)/ruff format .

# A first taste of the paper's evaluation: desk, quasi-random against cp-bo, 5 seeds each (a few
# minutes). The whole default evaluation is 1,500 runs: `make bench BENCH_ARGS=`.
BENCH_ARGS ?= --tasks desk --methods quasi-random,cp-bo --seeds 5
bench: setup
	$(BIN)/cpkb bench --out bench-out $(BENCH_ARGS)

clean:
	rm -rf $(VENV) build *.egg-info

# The image's pinned runtime dependencies, from this (tested) environment.
lock: setup
	$(BIN)/python deploy/lock.py
