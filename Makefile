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

test: setup
	@$(PY) -m pytest -q test

bench: setup
	@scripts/bench.sh

clean:
	rm -rf build $(VENV) diffavatar_core/_core*.so out
