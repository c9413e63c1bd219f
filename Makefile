# wheel_force_estimator: `make demo` and `make test` are all a fresh machine needs;
# `make test-all` adds the slow tier (what CI runs, `.ci/run`).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_DIR ?= demo_out
# Tests that start DDS participants stay on this machine and on their own domain.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export RMW_IMPLEMENTATION ?= rmw_fastrtps_cpp
export MPLBACKEND ?= Agg

.PHONY: venv test test-all demo bench bench-diagnose clean lint

venv: $(STAMP)

$(STAMP): setup.py setup.cfg package.xml requirements-dev.txt
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements-dev.txt
	$(BIN)/python -m pip install --quiet -e .
	touch $(STAMP)

# The ROS graph tests first, alone (their timing checks measure the node beside nothing else),
# then every other file on all cores.  `make test` is the fast tier (tests marked `slow`
# deselected); `make test-all` runs everything.  Both print the 25 slowest tests.  One BLAS
# thread per worker when the files share the cores: a worker per core each spinning two
# OpenBLAS threads oversubscribed them (the three longest fast-tier files, 2 workers:
# 205 s with the default threads, 149 s with one; docs/performance.md).  Files go to the
# workers in collection order, the files marked `long_file` first (test/conftest.py): by
# default pytest-xdist hands out the files with the most tests first, and the longest file,
# with few tests, ran last and alone.
PYTEST = AMENT_PREFIX_PATH=$(CURDIR)/$(VENV) $(BIN)/python -m pytest -q -p no:cacheprovider \
	--durations=25
PARALLEL = OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1
TIER ?= -m 'not slow'

test: venv
	$(PYTEST) $(TIER) test/test_ros_*.py
	$(PARALLEL) $(PYTEST) $(TIER) -n auto --dist loadfile --no-loadscope-reorder \
		--ignore-glob='*/test_ros_*.py' test

test-all: venv
	$(MAKE) test TIER=

lint: venv
	$(BIN)/ament_flake8 wheel_force_estimator test bench setup.py
	$(BIN)/ament_pep257 wheel_force_estimator test bench setup.py

demo: venv
	$(BIN)/python -m wheel_force_estimator.demo --out $(DEMO_DIR)

bench: venv
	for f in bench/bench_*.py; do echo "== $$f"; $(BIN)/python $$f || exit 1; done

bench-diagnose: venv
	$(BIN)/python bench/diagnose_blind.py
	$(BIN)/python bench/diagnose_bound.py
	$(BIN)/python bench/diagnose_joint.py

clean:
	rm -rf $(VENV) $(DEMO_DIR) build install log *.egg-info
