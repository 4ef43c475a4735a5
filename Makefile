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

# The suite runs on $(JOBS) processes (an idle one takes queued tests from the other: the slow
# ones sit anywhere); the tests that restart a shared server run alone after it.
# PYTEST_ARGS (e.g. a test file) runs those tests in one process instead.
JOBS ?= 2
test: setup
ifeq ($(strip $(PYTEST_ARGS)),)
	$(BIN)/pytest -q -n $(JOBS) --dist worksteal -m "not serial"
	$(BIN)/pytest -q -m serial
else
	$(BIN)/pytest -q $(PYTEST_ARGS)
endif

lint: setup
	$(BIN)/ruff check service client tests bench
	$(BIN)/ruff format --check service client tests bench
	$(BIN)/mypy

# Every benchmark at smoke size, $(JOBS) at a time (each starts its own services on free ports and
# temporary databases), the longest first; each one's output is printed whole when it ends.
SMOKES := paper_tables reuse_quality load mbm safety_soak real_robots pose_goals pose_cartesian \
	plan_hit transfer certify_sampling validation planning stats rejections ik lookup \
	exact_distances
SMOKE_mbm := bench/mbm.py --smoke --moveit --cross-scene
SMOKE_pose_cartesian := bench/pose_goals.py --smoke --cartesian

bench-smoke: setup
	$(MAKE) --no-print-directory -j$(JOBS) --output-sync=target $(addprefix smoke-,$(SMOKES))

smoke-%:
	$(BIN)/python $(or $(SMOKE_$*),bench/$*.py --smoke)

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
