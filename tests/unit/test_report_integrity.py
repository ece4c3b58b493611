"""A report never trusts a folder blindly: a malformed or partial result set is excluded with
its reason and the other runs are reported; a run with a _run.yaml and no info.csv is listed;
the report's header counts what was found, used and excluded."""
import csv
import glob
import os
import subprocess
import sys

import pytest

from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
REPORT = os.path.join(ROOT, "scripts", "report.py")


@pytest.fixture()
def four_runs(tmp_path):
    """Four finished graph-mode runs (grid, 2 robots, CR, 300 s): their prefixes."""
    res = tmp_path / "res"
    prefixes = []
    for seed in range(4):
        sim = GraphSimulator(GraphSimConfig(map="grid", robots=2, alg="CR", duration=300.0,
                                            seed=seed, results_dir=str(res)))
        sim.run()
        prefixes.append(sim.prefix)
    return res, prefixes


def _report(res, out):
    return subprocess.run([sys.executable, REPORT, str(res), "--out", str(out)],
                          capture_output=True, text=True)


def test_a_malformed_info_csv_and_a_missing_one_are_excluded_not_fatal(four_runs, tmp_path):
    res, (a, b, c, d) = four_runs
    with open(a + "_info.csv", "r+") as f:          # truncated: 7 of 22 fields
        text = f.read()
        f.seek(0)
        f.truncate()
        f.write(";".join(text.split(";")[:7]))
    os.remove(b + "_info.csv")                      # the monitor wrote none
    r = _report(res, tmp_path / "rep")
    assert r.returncode == 0, r.stderr
    with open(tmp_path / "rep" / "excluded.csv") as f:
        rows = {row["prefix"]: row for row in csv.DictReader(f)}
    assert set(rows) == {a, b}
    assert rows[a]["status"] == rows[b]["status"] == "UNREADABLE"
    assert "fields" in rows[a]["why"] and "_info.csv" in rows[a]["why"]
    assert "no _info.csv" in rows[b]["why"] and "TIMEOUT" in rows[b]["why"]
    with open(tmp_path / "rep" / "runs.csv") as f:
        assert len(list(csv.DictReader(f))) == 2    # c and d
    html = (tmp_path / "rep" / "report.html").read_text()
    assert "4 result set(s) found" in html and "2 used, 2 excluded (2 UNREADABLE" in html
    assert c and d


def test_a_folder_of_only_damaged_runs_is_one_line_and_exit_2(four_runs, tmp_path):
    res, prefixes = four_runs
    for p in prefixes:
        with open(p + "_info.csv", "w") as f:
            f.write("garbage\n")
    r = _report(res, tmp_path / "rep")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "UNREADABLE" in r.stderr
    assert not glob.glob(str(tmp_path / "rep" / "*.html"))
