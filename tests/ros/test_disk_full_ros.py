"""A full disk under a full-stack run: the runner ends it with one result line naming the
files and the space left (status ABORTED, exit 1), no traceback, no temporary file."""
import os
import subprocess
import sys

from rosenv import ros_env

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from small_fs import reported_leftovers, require_small_fs, small_fs_argv  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")


def test_full_stack_on_a_full_disk(tmp_path):
    require_small_fs(tmp_path)
    out = tmp_path / "small"
    argv = ["/usr/bin/python3", START, "--headless", "--map", "grid", "--robots", "2",
            "--alg", "CR", "--loc", "fake_localization", "--timeout", "600",
            "--speedup", "4", "--results-dir", str(out / "r")]
    r = subprocess.run(small_fs_argv(out, "48k", argv), env=ros_env(), capture_output=True,
                       text=True, timeout=300, start_new_session=True,
                       stdin=subprocess.DEVNULL)
    text = r.stdout + r.stderr
    assert r.returncode == 1, text[-3000:]
    assert "Traceback" not in text, text[-3000:]
    (result,) = [ln for ln in r.stdout.splitlines() if ln.startswith("result: ")]
    assert result.startswith("result: ABORTED: no space left on device writing "), result
    assert "bytes free on its file system" in result and str(out) in result, result
    assert reported_leftovers(r.stdout) == [], r.stdout
