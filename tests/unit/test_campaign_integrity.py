"""A campaign owns its folder: a second campaign command on the same folder fails at once and
nothing runs twice; a folder holding another campaign is refused (unless --force-new, and
then the report uses only the new campaign's runs); resuming verifies each finished run's
files and runs a damaged one again, counted once; an empty grid is said."""
import csv
import glob
import os
import subprocess
import sys
import time

import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPT = os.path.join(ROOT, "scripts", "campaign.py")


def _campaign(tmp_path, name="c.yaml", seeds=2, duration=300, alg=("CR",)):
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"name": "integrity", "mode": "graph",
                                    "fixed": {"duration": duration},
                                    "grid": {"map": ["grid"], "robots": [2],
                                             "alg": list(alg)},
                                    "seeds": seeds}))
    return str(path)


def _cli(*args, **kw):
    return subprocess.run([sys.executable, SCRIPT, *args, "--workers", "1"],
                          capture_output=True, text=True, stdin=subprocess.DEVNULL, **kw)


def _rows(out):
    with open(os.path.join(out, "runs.csv")) as f:
        return list(csv.DictReader(f))


def _infos(out):
    return glob.glob(os.path.join(out, "results", "**", "*_info.csv"), recursive=True)


def test_a_second_campaign_on_the_same_folder_fails_at_once(tmp_path):
    out = str(tmp_path / "out")
    camp = _campaign(tmp_path, seeds=30, duration=3600)
    first = subprocess.Popen([sys.executable, SCRIPT, camp, "--out", out, "--workers", "1",
                              "--no-report"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, stdin=subprocess.DEVNULL)
    lock = os.path.join(out, ".campaign.lock")
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (os.path.exists(lock)
                                               and os.path.getsize(lock)):
        time.sleep(0.05)
    second = _cli(camp, "--out", out, "--no-report")
    first_running = first.poll() is None     # the second did not wait for the lock
    first_out, first_err = first.communicate(timeout=300)
    assert first.returncode == 0, first_err
    assert second.returncode == 2, second.stdout + second.stderr
    lines = second.stderr.strip().splitlines()
    assert len(lines) == 1 and "in use by another campaign" in lines[0]
    assert f"pid {first.pid}" in lines[0]
    assert first_running                     # at once: it failed while the first ran
    assert len(_rows(out)) == 30 and len(_infos(out)) == 30     # nothing ran twice
    again = _cli(camp, "--out", out, "--no-report")                # the lock is released
    assert again.returncode == 0 and "30 already done" in again.stdout, again.stderr


def test_a_folder_of_another_campaign_is_refused_unless_force_new(tmp_path):
    out = str(tmp_path / "out")
    assert _cli(_campaign(tmp_path, seeds=3), "--out", out).returncode == 0
    other = _campaign(tmp_path, "other.yaml", seeds=2, alg=("CGG",))
    r = _cli(other, "--out", out)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "holds another campaign" in r.stderr and "--force-new" in r.stderr
    assert len(_rows(out)) == 3                                    # untouched
    r = _cli(other, "--out", out, "--force-new")
    assert r.returncode == 0, r.stderr
    assert [row["alg"] for row in _rows(out)] == ["CGG", "CGG"]
    with open(os.path.join(out, "report", "runs.csv")) as f:      # only its own runs
        assert {row["algorithm"] for row in csv.DictReader(f)} == {"CGG"}


def test_a_damaged_finished_run_is_run_again_and_counted_once(tmp_path):
    out = str(tmp_path / "out")
    camp = _campaign(tmp_path, seeds=3)
    assert _cli(camp, "--out", out).returncode == 0
    infos = sorted(_infos(out))
    with open(infos[1], "r+") as f:                                # truncated
        f.truncate(20)
    r = _cli(camp, "--out", out)
    assert r.returncode == 0, r.stderr
    assert "redone: 1 finished run(s)" in r.stdout and "run again" in r.stdout
    rows = _rows(out)
    assert len(rows) == 3 and {row["status"] for row in rows} == {"TIMEOUT"}
    assert len(_infos(out)) == 3                                   # the damaged one replaced
    with open(os.path.join(out, "report", "runs.csv")) as f:
        assert len(list(csv.DictReader(f))) == 3
    os.remove(sorted(_infos(out))[0])                              # a deleted file too
    r = _cli(camp, "--out", out)
    assert "redone: 1" in r.stdout and len(_infos(out)) == 3


def test_an_empty_grid_is_said(tmp_path):
    path = tmp_path / "empty.yaml"
    path.write_text(yaml.safe_dump({"name": "e", "mode": "graph", "grid": {},
                                    "fixed": {"duration": 60}}))
    r = _cli(str(path), "--out", str(tmp_path / "out"), "--dry-run")
    assert r.returncode == 0, r.stderr
    assert "grid and seeds vary nothing" in r.stderr
