# Two commands do all set-up on a fresh machine:  make demo   and   make test
# Every process started from here keeps DDS discovery on this machine.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export PYTHONUNBUFFERED := 1

VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: venv demo test lint bench colcon clean

venv:
	@bash tools/bootstrap.sh

demo: venv
	$(PY) -m stiction_ros.cli.study --out docs

test: venv
	$(PY) -m pytest -q test

lint: venv
	$(PY) -m pytest -q test/test_flake8.py test/test_pep257.py

bench: venv
	$(PY) -m bench.run_all

colcon: venv
	$(VENV)/bin/colcon build --base-paths . --build-base /tmp/stiction_ros_colcon/build \
	  --install-base /tmp/stiction_ros_colcon/install

clean:
	rm -rf $(VENV) build install log .pytest_cache
