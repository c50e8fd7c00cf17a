# hnnbench: `make benchmark` runs the whole benchmark, `make test` runs the tests.
# Both set up .venv first (scripts/maintainer/setup.sh; idempotent).
SHELL := /bin/bash
VENV := .venv/bin
# The measured-pendulum data: $HNNBENCH_DATA_DIR, else ../shared/... beside the clone.
export HNNBENCH_DATA_DIR ?= $(abspath ../shared/data/schmidt-lipson-2009)
# Parallel jobs of `make benchmark`: one per usable core (each job pins itself to one).
# (GNU nproc honours OMP_NUM_THREADS, which hnnbench sets to 1 for its jobs: ignore it.)
JOBS ?= $(shell env -u OMP_NUM_THREADS nproc 2>/dev/null || echo 1)
# What `make benchmark` sweeps, e.g. SYSTEMS=spring,pendulum MODELS=hnn_jax,mlp_jax.
SYSTEMS ?= all
MODELS ?= all
# Seeds of `make benchmark` (the committed leaderboard is built by scripts/maintainer/paper_sweep.sh:
# seeds 0-9 of the JAX twins, the oracle and standing_still; 0-2 of the torch twins).
SEEDS ?= 0
PYTEST_ARGS ?=
# `make test`, `test-fast`, `integration` and `e2e` run the tests in PYTEST_WORKERS
# processes (pytest-xdist; 0: in this process), each test file in one of them, so a
# module's fixtures (a cluster, a shared sweep) are set up once.
PYTEST_WORKERS ?= 2
PARALLEL := -n $(PYTEST_WORKERS) --dist loadfile

.PHONY: setup benchmark benchmark-serial quick test test-fast unit integration e2e \
	test-distributed fuzz lint typecheck imports clean \
	ci-reference guard-reference

setup:
	@scripts/maintainer/setup.sh

# Every system x every model, paper settings, seed(s) $(SEEDS); one joblib worker per core.
# The records are the same as a serial run's (tests/e2e/test_launchers.py).
benchmark: setup
	$(VENV)/hnnbench -m system=$(SYSTEMS) model=$(MODELS) seed=$(SEEDS) hydra/launcher=joblib hydra.launcher.n_jobs=$(JOBS)

# The same, one job at a time in this process.
benchmark-serial: setup
	$(VENV)/hnnbench -m system=$(SYSTEMS) model=$(MODELS) seed=$(SEEDS)

quick: setup
	$(VENV)/hnnbench -m system=all model=all profile=quick hydra/launcher=joblib hydra.launcher.n_jobs=$(JOBS)

# The CI gate's reference (tests/e2e/test_ci_gate.py sweeps exactly the pairs it holds):
# every system x the JAX twin of every neural family + the oracle and the standing_still
# reference, and the torch twins on the spring; quick, seed 0.
GATE_MODELS := mlp_jax,hnn_jax,dhnn_jax,lnn_jax,so_mlp_jax,srnn_jax,oracle,standing_still
GATE_TORCH := mlp_torch,hnn_torch,dhnn_torch,lnn_torch,so_mlp_torch,srnn_torch
GATE_DIR := results/runs/ci-reference
ci-reference: setup
	rm -rf $(GATE_DIR)
	$(VENV)/hnnbench -m system=all model=$(GATE_MODELS) profile=quick seed=0 \
	  hydra/launcher=joblib hydra.launcher.n_jobs=$(JOBS) hydra.sweep.dir=$(GATE_DIR)/jax
	$(VENV)/hnnbench -m system=spring model=$(GATE_TORCH) profile=quick seed=0 \
	  hydra/launcher=joblib hydra.launcher.n_jobs=$(JOBS) hydra.sweep.dir=$(GATE_DIR)/torch
	$(VENV)/hnnbench check $(GATE_DIR)/jax $(GATE_DIR)/torch \
	  --reference results/reference/quick.csv --update
	$(VENV)/python scripts/maintainer/job_costs.py

# The reproduction guard's reference (tests/e2e/test_reproduction_guard.py).
guard-reference: setup
	$(VENV)/python tests/e2e/test_reproduction_guard.py --update

test: setup
	$(VENV)/ruff check .
	$(VENV)/ruff format --check .
	$(VENV)/mypy
	$(VENV)/lint-imports
	$(VENV)/python -m pytest $(PARALLEL) $(PYTEST_ARGS)

# Real one-node Slurm and Ray clusters on this machine (scripts/maintainer/cluster/, as root:
# installs slurm/munge/MariaDB with apt-get, ray + hydra-ray-launcher into .venv/ray-site).
# `make test` runs them too (pytest selects every marker).
test-distributed: setup
	$(VENV)/python -m pytest -m distributed -v $(PYTEST_ARGS)

# The property tests with fresh random examples, FUZZ_RUNS times (the gate's are fixed).
FUZZ_RUNS ?= 10
fuzz: setup
	for i in $$(seq $(FUZZ_RUNS)); do HNNBENCH_HYPOTHESIS=explore $(VENV)/python -m pytest \
	  $$(grep -rl "from hypothesis" tests) -q -p no:cacheprovider $(PYTEST_ARGS) || exit 1; done

test-fast: setup
	$(VENV)/python -m pytest -m "not slow" $(PARALLEL) $(PYTEST_ARGS)

# The tests by kind (CONTRIBUTING.md): tests/unit (no job, no sweep, no subprocess;
# under a minute: the inner loop), tests/integration (jobs, sweeps, reports and models
# in process), tests/e2e (the console script, wheels, plugin packages, launchers,
# clusters, notebooks, benchmark scripts).
unit: setup
	$(VENV)/python -m pytest tests/unit -q $(PYTEST_ARGS)

integration: setup
	$(VENV)/python -m pytest tests/integration $(PARALLEL) $(PYTEST_ARGS)

e2e: setup
	$(VENV)/python -m pytest tests/e2e $(PARALLEL) $(PYTEST_ARGS)

lint: setup
	$(VENV)/ruff check .
	$(VENV)/ruff format --check .

typecheck: setup
	$(VENV)/mypy

# The core's layers import only downward and form no cycle (pyproject.toml,
# [tool.importlinter]; docs/ARCHITECTURE.md).
imports: setup
	$(VENV)/lint-imports

clean:
	rm -rf .venv build dist *.egg-info .pytest_cache .ruff_cache .mypy_cache
