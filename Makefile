# patrolling_sim workspace. Every target works on a fresh Debian 12 machine as root.
SHELL := /bin/bash
export PATH := /usr/bin:/bin:/usr/sbin:/sbin:$(PATH)
PYTEST_ARGS ?=
# `make run` experiment (override on the command line, e.g. `make run ALG=SEBS ROBOTS=6`)
MAP ?= grid
ROBOTS ?= 4
ALG ?= CGG
LOC ?= fake_localization
TIMEOUT ?= 300
SPEEDUP ?= 5
RESULTS ?= results

.PHONY: setup build run test unit rostest lint docs clean

## setup: install the Debian packages (only if missing) and build the workspace
setup:
	bash scripts/setup.sh

## build: incremental catkin_make (assumes setup ran once)
build:
	catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release > build.log 2>&1 || (tail -40 build.log; exit 1)

## run: setup, one headless experiment (full ROS stack: simulator, navigation, agents,
## monitor), then the report (summary table and plots) of everything under $(RESULTS)/
run: setup
	/usr/bin/python3 scripts/start_experiments.py --headless --map $(MAP) --robots $(ROBOTS) \
		--alg $(ALG) --loc $(LOC) --timeout $(TIMEOUT) --speedup $(SPEEDUP) --results-dir $(RESULTS)
	/usr/bin/python3 scripts/report.py $(RESULTS)/$(MAP)_$(ROBOTS)/$(ALG) --out $(RESULTS)/report
	@echo "report: $(RESULTS)/report/report.html (plots: $(RESULTS)/report/*.png)"

## test: setup, then every unit test and every rostest, one pytest summary at the end; two
## pytest-xdist workers: the ROS tests one after another on one, the unit tests on the other
test: setup
	/usr/bin/python3 -m pytest -p no:cacheprovider -n 2 --dist loadgroup tests $(PYTEST_ARGS)

## unit: only the pure-Python unit tests (no ROS master, no build needed)
unit:
	/usr/bin/python3 -m pytest -p no:cacheprovider tests/unit $(PYTEST_ARGS)

## rostest: only the ROS integration tests
rostest: setup
	/usr/bin/python3 -m pytest -p no:cacheprovider tests/ros $(PYTEST_ARGS)

## lint: flake8 (Debian's python3-flake8, config in .flake8) over every Python file
lint:
	/usr/bin/python3 -m flake8 src scripts bench tests $(wildcard src/*/nodes/*)

## docs: the API reference from the docstrings (Sphinx; warnings are errors): build/docs/
docs:
	bash scripts/build_api_docs.sh

clean:
	rm -rf build devel install build.log
