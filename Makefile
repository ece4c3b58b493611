# patrolling_sim workspace. Every target works on a fresh Debian 12 machine as root.
SHELL := /bin/bash
export PATH := /usr/bin:/bin:/usr/sbin:/sbin:$(PATH)
PYTEST_ARGS ?=

.PHONY: setup build test unit rostest clean

## setup: install the Debian packages (only if missing) and build the workspace
setup:
	bash scripts/setup.sh

## build: incremental catkin_make (assumes setup ran once)
build:
	catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release > build.log 2>&1 || (tail -40 build.log; exit 1)

## test: setup, then every unit test and every rostest, one pytest summary at the end
test: setup
	/usr/bin/python3 -m pytest -p no:cacheprovider tests $(PYTEST_ARGS)

## unit: only the pure-Python unit tests (no ROS master, no build needed)
unit:
	/usr/bin/python3 -m pytest -p no:cacheprovider tests/unit $(PYTEST_ARGS)

## rostest: only the ROS integration tests
rostest: setup
	/usr/bin/python3 -m pytest -p no:cacheprovider tests/ros $(PYTEST_ARGS)

clean:
	rm -rf build devel install build.log
