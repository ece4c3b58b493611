"""Driving a Tk window from a test: process its events until a condition holds."""
import time

import pytest


def pump(root, cond, timeout, what, state=lambda: ""):
    """Run ``root``'s event loop until ``cond()`` is true; fail the test after ``timeout`` wall
    s, naming ``what`` was awaited and ``state()`` (e.g. the window's status line)."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        root.update()
        if cond():
            return
        time.sleep(0.05)
    pytest.fail(f"GUI: {what} not seen within {timeout} s; {state()}")
