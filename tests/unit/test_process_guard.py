"""tests/process_guard.py: the groups tests start are recorded, and what is left of them when
the session ends is stopped (SIGTERM, then SIGKILL), and nothing else."""
import os
import signal
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import process_guard  # noqa: E402
from patrolling_sim.runner.proctree import proc_stat  # noqa: E402


def _spawn(script):
    p = subprocess.Popen(["bash", "-c", script], start_new_session=True)
    return p


def _wait_members(pgid, n):
    import time
    for _ in range(100):
        if len(process_guard.members(pgid)) >= n:
            return
        time.sleep(0.05)


def test_a_group_started_in_a_new_session_is_recorded():
    p = _spawn("sleep 300")
    try:
        assert p.pid in process_guard._started
    finally:
        process_guard._started.pop(p.pid, None)
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()


def test_orphans_of_a_dead_leader_are_stopped():
    """The leader dies (SIGKILL, no clean-up); its two children, still in the group, are found
    and stopped by the group's id."""
    p = _spawn("sleep 300 & sleep 300 & wait")
    process_guard._started.pop(p.pid, None)      # this test stops it itself
    start = proc_stat(p.pid).starttime
    _wait_members(p.pid, 3)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    left = process_guard.members(p.pid, start)
    assert len(left) == 2
    stopped = process_guard.stop_groups({p.pid: start}, grace=10)
    assert sorted(stopped[p.pid]) == sorted(left)
    assert process_guard.members(p.pid) == []


def test_a_group_that_ignores_sigterm_gets_sigkill():
    p = _spawn("trap '' TERM; sleep 300 & wait")
    process_guard._started.pop(p.pid, None)
    start = proc_stat(p.pid).starttime
    _wait_members(p.pid, 2)
    stopped = process_guard.stop_groups({p.pid: start}, grace=0.5)
    p.wait()
    assert p.pid in stopped and process_guard.members(p.pid) == []


def test_a_live_leader_with_another_start_time_is_not_ours():
    p = _spawn("sleep 300")
    process_guard._started.pop(p.pid, None)
    try:
        start = proc_stat(p.pid).starttime
        _wait_members(p.pid, 1)
        assert process_guard.members(p.pid, start + 1) == []
        assert process_guard.stop_groups({p.pid: start + 1}, grace=0.5) == {}
        assert p.poll() is None                    # untouched
    finally:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()


SLEEPER_TEST = '''
import os, subprocess, time
def test_sleeps():
    p = subprocess.Popen(["bash", "-c", "trap '' TERM; sleep 300"], start_new_session=True)
    with open(os.environ["GUARD_PIDFILE"], "w") as f:
        f.write(str(p.pid))
    time.sleep(300)
'''


def test_sigterm_to_an_xdist_session_stops_what_its_workers_started(tmp_path):
    """``make test`` runs pytest-xdist workers; a CI timeout's SIGTERM reaches only the
    controller, which interrupts its workers and kills them 10 s later. A worker's process
    guard must stop what its tests started before that: here a group that ignores SIGTERM,
    so only the SIGKILL after the worker's shorter grace stops it."""
    import time
    (tmp_path / "test_sleeper.py").write_text(SLEEPER_TEST)
    pidfile = tmp_path / "sleeper.pid"
    env = dict(os.environ, GUARD_PIDFILE=str(pidfile),
               PYTHONPATH=os.path.join(os.path.dirname(__file__), "..") + os.pathsep
               + os.environ.get("PYTHONPATH", ""))
    p = subprocess.Popen([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p",
                          "conftest", "-n", "1", "-q", "test_sleeper.py"], cwd=str(tmp_path),
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         start_new_session=True)
    sleeper = None
    try:
        for _ in range(1200):                   # the worker's test has started its group
            if pidfile.exists() and pidfile.read_text():
                sleeper = int(pidfile.read_text())
                break
            time.sleep(0.05)
        assert sleeper is not None, "the sleeper test never started"
        p.send_signal(signal.SIGTERM)
        out, _ = p.communicate(timeout=120)
        for _ in range(200):                    # SIGKILL is delivered asynchronously
            if not process_guard.members(sleeper):
                break
            time.sleep(0.05)
        assert not process_guard.members(sleeper), f"the test's group survived:\n{out}"
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        if sleeper is not None and process_guard.members(sleeper):
            os.killpg(sleeper, signal.SIGKILL)


def test_an_interrupt_during_the_grace_goes_straight_to_sigkill():
    """A second Ctrl-C (or execnet's SIGINT to a finishing xdist worker) while the guard waits
    for SIGTERM to work must not leave the group running: it cuts the grace short."""
    import threading
    p = _spawn("trap '' TERM; sleep 300 & wait")
    process_guard._started.pop(p.pid, None)
    start = proc_stat(p.pid).starttime
    _wait_members(p.pid, 2)
    threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT)).start()
    stopped = process_guard.stop_groups({p.pid: start}, grace=60)
    p.wait()
    assert p.pid in stopped and process_guard.members(p.pid) == []
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
