"""Runs every ``src/<pkg>/test/*.test`` through rostest (own master on a random port)."""
import glob
import os
import signal
import subprocess

import pytest

from rosenv import discover_rostests, junit_summary, run_rostest
from test_experiments import own_processes

CASES = discover_rostests()


@pytest.mark.parametrize("pkg,path", CASES, ids=[f"{p}/{os.path.basename(f)}" for p, f in CASES])
def test_rostest(pkg, path, tmp_path):
    proc = run_rostest(pkg, path, tmp_path)
    tests, failures, errors, msgs = junit_summary(str(tmp_path))
    tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-40:])
    assert proc.returncode == 0, f"rostest exited {proc.returncode}:\n{tail}"
    assert tests > 0, f"rostest produced no JUnit results:\n{tail}"
    assert failures == 0 and errors == 0, "\n".join(msgs) + "\n" + tail


def test_a_stopped_rostest_stops_its_nodes(tmp_path):
    """A rostest ended from outside (here its timeout; Ctrl-C and pytest's SIGTERM take the
    same path) stops the nodes it launched: roslaunch starts each in a session of its own,
    so a killed rostest would leave them running (every node's command line names its log
    folder under ``tmp_path``)."""
    pkg, path = next((p, f) for p, f in CASES if f.endswith("patrol_run.test"))
    with pytest.raises(subprocess.TimeoutExpired):   # the test itself takes about 30 s
        run_rostest(pkg, path, tmp_path, timeout=12)
    started = glob.glob(os.path.join(str(tmp_path), "log", "*", "*-stdout.log"))
    left = own_processes(str(tmp_path))
    for pid in left:                 # ours (they name this test's folder): do not leak them
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    assert started, "rostest had started no node 12 s after its start (nothing to check)"
    assert left == [], f"processes of the stopped rostest still running: {left}"
