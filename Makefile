# Two commands: `make serve` sets up and runs the service; `make test` sets up and runs the tests.
# `make serve` installs the package alone; `make test` (and lint, bench-smoke) adds the dev extras.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
RUNTIME := $(VENV)/.installed-runtime
DEV := $(VENV)/.installed-dev

.PHONY: setup serve test lint bench-smoke clean

$(RUNTIME): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e .
	$(BIN)/trajcache warm  # numba's cache, with its progress
	touch $(RUNTIME)

$(DEV): $(RUNTIME)
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(DEV)

setup: $(DEV)

serve: $(RUNTIME)
	$(BIN)/trajcache serve

# The suite runs on $(JOBS) processes; the tests that restart a shared server run alone after it.
# PYTEST_ARGS (e.g. a test file) runs those tests in one process instead.
JOBS ?= 2
test: setup
ifeq ($(strip $(PYTEST_ARGS)),)
	$(BIN)/pytest -q -n $(JOBS) -m "not serial"
	$(BIN)/pytest -q -m serial
else
	$(BIN)/pytest -q $(PYTEST_ARGS)
endif

lint: setup
	$(BIN)/ruff check service client tests bench
	$(BIN)/ruff format --check service client tests bench
	$(BIN)/mypy

bench-smoke: setup
	$(BIN)/python bench/validation.py --smoke
	$(BIN)/python bench/lookup.py --smoke
	$(BIN)/python bench/plan_hit.py --smoke
	$(BIN)/python bench/stats.py --smoke
	$(BIN)/python bench/reuse_quality.py --smoke
	$(BIN)/python bench/planning.py --smoke
	$(BIN)/python bench/paper_tables.py --smoke
	$(BIN)/python bench/safety_soak.py --smoke
	$(BIN)/python bench/load.py --smoke
	$(BIN)/python bench/real_robots.py --smoke
	$(BIN)/python bench/rejections.py --smoke
	$(BIN)/python bench/mbm.py --smoke --moveit --cross-scene
	$(BIN)/python bench/ik.py --smoke
	$(BIN)/python bench/pose_goals.py --smoke
	$(BIN)/python bench/pose_goals.py --smoke --cartesian
	$(BIN)/python bench/certify_sampling.py --smoke
	$(BIN)/python bench/transfer.py --smoke

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
