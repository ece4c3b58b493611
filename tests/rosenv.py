"""Helpers to run ROS integration tests from pytest.

Each rostest runs in its own ROS_HOME (logs, JUnit XML) with an environment built from
``devel/setup.bash`` and ``/usr/bin`` first on PATH (Debian's rostest helpers use
``/usr/bin/env python3``). A rostest passes only if its exit code is 0 *and* its JUnit XML
files report tests with no failure or error.
"""
import glob
import os
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
                    msgs.append(f"{case.get('name')}: {(bad.get('message') or bad.text or '')[:500]}")
    return tests, failures, errors, msgs


def run_rostest(pkg, path, ros_home, timeout=600, args=()):
    env = dict(ros_env())
    env["ROS_HOME"] = str(ros_home)
    env["ROS_LOG_DIR"] = os.path.join(str(ros_home), "log")
    proc = subprocess.run(["rostest", pkg, os.path.basename(path), *args], env=env,
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    return proc
