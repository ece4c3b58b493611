"""Fixtures shared by the ROS tests."""
import shutil
import subprocess

import pytest


@pytest.fixture(scope="session")
def xvfb():
    """A virtual X display (``:N``) for GUI tests, one per test process, stopped at its end.
    One per process, not per test: Tk keeps its display connection after its window is
    destroyed, and when that display goes away Xlib ends the whole process (a second GUI test
    in the same pytest worker then took the worker down). Xvfb is started directly, not
    through xvfb-run: xvfb-run (a /bin/sh script) leaves its temporary folder in /tmp when it
    is ended by a signal."""
    if shutil.which("Xvfb") is None:
        pytest.fail("Xvfb not installed (package xvfb; make setup installs it)")
    proc = subprocess.Popen(["Xvfb", "-displayfd", "1", "-screen", "0", "1024x768x24",
                             "-nolisten", "tcp"], stdout=subprocess.PIPE, text=True)
    display = ":" + proc.stdout.readline().strip()
    try:
        yield display
    finally:
        proc.terminate()
        proc.wait(timeout=10)
