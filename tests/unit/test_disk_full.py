"""A full disk while a run writes its results: one line naming the files and the space left,
exit 1, no traceback, no temporary file; what could be recorded is marked ABORTED."""
import errno
import os
import subprocess
import sys

import pytest

from patrolling_sim.common.errors import NoSpaceError, free_bytes, is_no_space
from patrolling_sim.common.textfile import write_atomic
from patrolling_sim.monitor import run_status
from patrolling_sim.runner.outcome import no_space_record

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from small_fs import (leftovers, reported_leftovers, require_small_fs,  # noqa: E402
                      small_fs_argv)

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
GRAPH_SIM = os.path.join(ROOT, "scripts", "graph_sim.py")


@pytest.mark.parametrize("size", ["8k", "40k"])
def test_graph_mode_on_a_full_disk(tmp_path, size):
    """8k: full while the files are opened; 40k: full during the run (the trace files grow
    past it within the 3000 s run)."""
    require_small_fs(tmp_path)
    out = tmp_path / "small"
    argv = [sys.executable, GRAPH_SIM, "--map", "grid", "--robots", "4", "--alg", "CR",
            "--duration", "3000", "--results-dir", str(out / "r"), "--quiet"]
    r = subprocess.run(small_fs_argv(out, size, argv), capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 1, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "no space left on device writing" in lines[0] and str(out) in lines[0], lines
    assert "bytes free on its file system" in lines[0], lines
    assert reported_leftovers(r.stdout) == [], r.stdout


def test_write_atomic_leaves_no_temporary_file(tmp_path, monkeypatch):
    path = tmp_path / "x_info.csv"
    path.write_text("old\n")

    def full(src, dst):
        raise OSError(errno.ENOSPC, "No space left on device", src)
    monkeypatch.setattr(os, "replace", full)
    with pytest.raises(OSError) as e:
        write_atomic(str(path), "new\n")
    assert is_no_space(e.value) and e.value.filename == str(path)
    assert path.read_text() == "old\n" and leftovers(tmp_path) == []


def test_no_space_error_names_the_file_and_the_space_left(tmp_path):
    e = NoSpaceError(str(tmp_path / "a" / "b_*"))     # the folder need not exist
    assert str(e).startswith(f"no space left on device writing {tmp_path}/a/b_* (")
    assert e.free == free_bytes(str(tmp_path)) and f"{e.free} bytes free" in str(e)
    assert not is_no_space(OSError(errno.EACCES, "denied")) and not is_no_space(ValueError())


def test_the_runner_blames_a_full_disk_only_when_it_is_full(tmp_path, monkeypatch):
    import patrolling_sim.runner.outcome as outcome
    crashed = {"status": run_status.CRASHED, "reason": "the monitor ended without writing "
               "info.csv", "culprit": {"node": "monitor"}, "robots": [], "signal": None}
    prefix = str(tmp_path / "run")
    monkeypatch.setattr(outcome, "free_bytes", lambda p: 10 << 20)
    assert no_space_record(prefix, crashed, []) is None            # room left: not the disk
    monkeypatch.setattr(outcome, "free_bytes", lambda p: 0)
    rec = no_space_record(prefix, crashed, [])
    assert rec["status"] == run_status.ABORTED and "no space left" in rec["reason"]
    done = dict(crashed, status=run_status.TIMEOUT)
    assert no_space_record(prefix, done, []) is None                # a complete run stays
    assert no_space_record(prefix, done, ["run_info.csv"])["status"] == run_status.ABORTED
    stopped = dict(crashed, status=run_status.INTERRUPTED, signal="SIGINT")
    assert no_space_record(prefix, stopped, []) is None             # the user's signal stays
