"""Helpers to run ROS integration tests from pytest.

Each rostest runs in its own ROS_HOME (logs, JUnit XML) with an environment built from
``devel/setup.bash`` and ``/usr/bin`` first on PATH (Debian's rostest helpers use
``/usr/bin/env python3``). A rostest passes only if its exit code is 0 *and* its JUnit XML
files report tests with no failure or error.
"""
import glob
import os
import signal
import subprocess
import xml.etree.ElementTree as ET

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


def ros_env():
    """The workspace's environment (``devel/setup.bash``, /usr/bin first on PATH, no
    ROS_MASTER_URI): the runner's own, so tests run ROS as experiments do."""
    from patrolling_sim.runner.rosenv import workspace_env
    return workspace_env()


def discover_rostests():
    """[(package, path-to-.test)] for every src/<pkg>/test/*.test."""
    out = []
    for path in sorted(glob.glob(os.path.join(ROOT, "src", "*", "test", "*.test"))):
        pkg = os.path.basename(os.path.dirname(os.path.dirname(path)))
        out.append((pkg, path))
    return out


def junit_summary(ros_home):
    """(tests, failures, errors, [messages]) over all JUnit XML files under ros_home."""
    tests = failures = errors = 0
    msgs = []
    for f in glob.glob(os.path.join(ros_home, "test_results", "**", "*.xml"), recursive=True):
        root = ET.parse(f).getroot()
        suites = [root] if root.tag == "testsuite" else root.findall("testsuite")
        for s in suites:
            tests += int(s.get("tests", 0))
            failures += int(s.get("failures", 0))
            errors += int(s.get("errors", 0))
            for case in s.iter("testcase"):
                for bad in list(case.findall("failure")) + list(case.findall("error")):
                    msgs.append(
                        f"{case.get('name')}: {(bad.get('message') or bad.text or '')[:500]}")
    return tests, failures, errors, msgs


#: wall s that rostest gets after SIGINT to stop its nodes before it is killed: roslaunch
#: itself gives a node 15 s after SIGINT, then 2 s after SIGTERM (a bound, not a wait)
STOP_GRACE = 30.0


def stop_rostest(proc):
    """Stop a running rostest as Ctrl-C in its terminal would: SIGINT, so that it shuts its
    launch down (roslaunch starts every node in a session of its own, which a signal to
    rostest's group does not reach, and which would outlive a killed rostest), then SIGKILL
    if it is still running after ``STOP_GRACE`` s. Returns its whole (stdout, stderr)."""
    try:
        proc.send_signal(signal.SIGINT)
    except OSError:
        pass
    try:
        return proc.communicate(timeout=STOP_GRACE)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate()


def run_rostest(pkg, path, ros_home, timeout=600, args=()):
    """Run one rostest (its own session, so that the process guard knows it) and return its
    ``CompletedProcess``. On a timeout, Ctrl-C or pytest's SIGTERM the rostest is stopped with
    :func:`stop_rostest`, which lets it stop its nodes, and the exception goes on."""
    env = dict(ros_env())
    env["ROS_HOME"] = str(ros_home)
    env["ROS_LOG_DIR"] = os.path.join(str(ros_home), "log")
    cmd = ["rostest", pkg, os.path.basename(path), *args]
    with subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, cwd=ROOT, start_new_session=True) as proc:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired as e:    # its output goes with it, as run()'s does
            e.stdout, e.stderr = stop_rostest(proc)
            raise
        except BaseException:
            stop_rostest(proc)
            raise
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)
