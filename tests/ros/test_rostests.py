"""Runs every ``src/<pkg>/test/*.test`` through rostest (own master on a random port)."""
import os

import pytest

from rosenv import discover_rostests, junit_summary, run_rostest

CASES = discover_rostests()


@pytest.mark.parametrize("pkg,path", CASES, ids=[f"{p}/{os.path.basename(f)}" for p, f in CASES])
def test_rostest(pkg, path, tmp_path):
    proc = run_rostest(pkg, path, tmp_path)
    tests, failures, errors, msgs = junit_summary(str(tmp_path))
    tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-40:])
    assert proc.returncode == 0, f"rostest exited {proc.returncode}:\n{tail}"
    assert tests > 0, f"rostest produced no JUnit results:\n{tail}"
    assert failures == 0 and errors == 0, "\n".join(msgs) + "\n" + tail
