"""pytest configuration: make the workspace's pure-Python packages importable (in the tests
and in the programs they start) without sourcing devel/setup.bash, and share fixtures."""
import os
import signal
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
_SOURCES = [os.path.join(ROOT, "src", pkg, "src") for pkg in ("patrolling_sim", "spqrel_nav_lite")]
for p in _SOURCES:
    if p not in sys.path:
        sys.path.insert(0, p)
# ... and for the programs the tests start (scripts/*.py need the packages on their path, as
# `source devel/setup.bash` gives them)
os.environ["PYTHONPATH"] = os.pathsep.join(
    _SOURCES + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])


# --- the navigation's plan store (spqrel_nav_lite.plan_store) ----------------------------
# experiments started by the tests keep their navigation functions in a folder of this
# session, not in the user's ~/.cache; the experiments inherit the variable
if "PATROLLING_SIM_PLAN_STORE" not in os.environ:
    import atexit
    import shutil
    import tempfile
    _store = tempfile.mkdtemp(prefix="patrolling_sim_plan_store_")
    os.environ["PATROLLING_SIM_PLAN_STORE"] = _store
    atexit.register(shutil.rmtree, _store, ignore_errors=True)


# --- processes the tests started in groups of their own (tests/process_guard.py) ---------
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import process_guard  # noqa: E402


#: ROS test modules of the second ROS group (see pytest_collection_modifyitems); every other
#: module under tests/ros is in the first
ROS_SECOND = ("test_experiments.py", "test_scenarios_ros.py", "test_campaign_ros.py")
#: ROS test modules that run last, at the end of the second ROS group
ROS_LAST = ("test_abstract_fidelity.py",)
#: s between SIGTERM and SIGKILL to the groups tests left running (process_guard), in a plain
#: session and in a pytest-xdist worker
GRACE, WORKER_GRACE = 15.0, 1.0


def _sigterm_as_ctrl_c(signum, frame):
    raise KeyboardInterrupt(f"pytest received {signal.Signals(signum).name}")


def pytest_configure(config):
    process_guard.install()
    # a shell starts a background job with SIGINT ignored (and a script run by a CI system
    # may inherit that), and Python then keeps it ignored: pytest-xdist could not interrupt
    # its workers (execnet interrupts a worker's running test with SIGINT), and every process
    # the tests start would inherit the ignored signal. SIGINT is Ctrl-C here, as in a terminal
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    # a CI timeout's SIGTERM ends pytest as Ctrl-C does: teardown and sessionfinish run
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _sigterm_as_ctrl_c)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Three groups for ``make test``'s two workers (``-n 2 --dist loadgroup``), in this
    order: the unit tests, the first ROS group, the second ROS group. pytest-xdist gives the
    first two groups one worker each and the third to the worker that runs out of work first:
    the unit tests' worker (about 300 s of unit tests against 1000 s of the first ROS group).
    So two ROS tests run at a time for most of the session (each starts its own master on a
    free port; a ROS test uses about half a core to one core, bench/notes/BENCHMARKS.md
    "Setup and test suite"), and the tests within a group one after another. The modules of
    :data:`ROS_LAST` end the second group: they make several experiments at a time and take
    most of both cores. The groups are balanced from the durations ``.ci/run`` lists (tests
    of 10 s or more): the unit tests plus the second group against the first. Without xdist
    the marks do nothing; the order stays (unit tests first)."""
    ros = os.path.join(ROOT, "tests", "ros") + os.sep
    rank = {"unit": 0, "ros1": 1, "ros2": 2}

    def group_of(item):
        path = str(item.fspath)
        if not path.startswith(ros):
            return "unit"
        name = os.path.basename(path)
        return "ros2" if name in ROS_SECOND or name in ROS_LAST else "ros1"

    groups = {}
    for item in items:
        groups[item.nodeid] = g = group_of(item)
        item.add_marker(pytest.mark.xdist_group(g))
    items.sort(key=lambda item: (rank[groups[item.nodeid]],                  # stable
                                 os.path.basename(str(item.fspath)) in ROS_LAST))


def pytest_sessionfinish(session, exitstatus):
    # a pytest-xdist worker: on the controller's Ctrl-C or SIGTERM, execnet in the worker
    # waits 5 s for the running test, then sends the worker SIGINT; the controller kills the
    # worker 10 s after its request. So the groups left get SIGTERM and, 1 s later, SIGKILL,
    # well inside those 5 s (with 4 s a loaded CI machine let the kill come first)
    worker = hasattr(session.config, "workerinput")
    stopped = process_guard.stop_leftovers(grace=WORKER_GRACE if worker else GRACE)
    if stopped:
        lines = [f"group {g}: pids {', '.join(map(str, sorted(p)))}"
                 for g, p in sorted(stopped.items())]
        rep = session.config.pluginmanager.get_plugin("terminalreporter")
        msg = (f"process guard: stopped {len(stopped)} process group(s) that tests had started "
               f"and left running ({'; '.join(lines)})")
        if rep is not None:
            rep.write_line(msg, yellow=True)
        else:
            sys.stderr.write(msg + "\n")
