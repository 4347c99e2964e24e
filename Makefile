# The two commands of the README. Both bootstrap the environment (scripts/bootstrap.sh):
# a fresh machine needs nothing but Python 3.11, a C++ compiler, cmake and ninja.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST

.PHONY: setup demo test bench clean

setup:
	@scripts/bootstrap.sh

demo: setup
	@$(VENV)/bin/diffavatar demo --out out/demo

# one pytest-xdist worker per core (tests that share a cached result are kept on one worker by
# their xdist_group mark, hence loadgroup); each worker's core keeps its 2 OpenMP threads
TEST_WORKERS ?= $(shell nproc)
test: setup
	@$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadgroup test

bench: setup
	@scripts/bench.sh

clean:
	rm -rf build $(VENV) diffavatar_core/_core*.so out
