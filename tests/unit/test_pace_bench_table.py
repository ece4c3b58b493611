"""bench/pace_bench.py's table: per-seed lines, the mean line over the seeds, and
``--table-from`` on a bad file."""
import importlib.util
import json
import os
import subprocess
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPT = os.path.join(ROOT, "bench", "pace_bench.py")


def load():
    spec = importlib.util.spec_from_file_location("pace_bench", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def row(alg, seed, pace, avg, mx):
    return {"alg": alg, "seed": seed, "rep": 0, "pace": pace, "avg": avg, "max": mx,
            "achieved": pace, "holds": 1, "timeouts": 0}


def test_mean_line_over_the_seeds():
    pb = load()
    rows = [row("CGG", 1, 1.0, 40.0, 100.0), row("CGG", 1, 8.0, 44.0, 110.0),
            row("CGG", 2, 1.0, 50.0, 200.0), row("CGG", 2, 8.0, 46.0, 190.0),
            row("SEBS", 1, 1.0, 30.0, 60.0), row("SEBS", 1, 8.0, 33.0, 66.0)]
    lines = pb.table(rows, [1.0, 8.0]).splitlines()
    mean = [ln for ln in lines if "| mean |" in ln]
    # CGG has two seeds: (40 + 50) / 2 = 45 at x1, (44 + 46) / 2 = 45 at x8; maxima 150 / 150
    assert mean == ["| CGG | mean | 45.0 / 45.0 | 150.0 / 150.0 | 0.0% | 0.0% | | | |"]
    # the mean line follows CGG's last seed; SEBS (one seed) gets none
    assert lines.index(mean[0]) == 4
    assert lines[3].startswith("| CGG | 2 |") and "10.0%" not in lines[3]
    assert "| CGG | 1 | 40.0 / 44.0 | 100.0 / 110.0 | 10.0% | 10.0% |" in lines[2]


def test_interferences_column_per_pace():
    pb = load()
    rows = [dict(row("CGG", 1, 2.0, 44.1, 201.9), interferences=10),
            dict(row("CGG", 1, 8.0, 51.4, 220.9), interferences=14)]
    lines = pb.table(rows, [2.0, 8.0]).splitlines()
    assert lines[0].endswith("| holds (timed out) | interferences |")
    assert lines[2].endswith("| 1 (0) / 1 (0) | 10 / 14 |")
    # runs recorded without the figure (older --json files) print a dash
    lines = pb.table([row("CGG", 1, 2.0, 44.1, 201.9)], [2.0]).splitlines()
    assert lines[2].endswith("| 1 (0) | - |")


def test_mean_is_none_where_a_seed_is_missing():
    pb = load()
    rows = [row("CGG", 1, 1.0, 40.0, 100.0), row("CGG", 1, 8.0, 44.0, 110.0),
            row("CGG", 2, 1.0, 50.0, 200.0)]
    avg, mx = pb.seed_means(rows, "CGG", [1.0, 8.0])
    assert avg == [45.0, None] and mx == [150.0, None]


def test_table_from_json(tmp_path):
    f = tmp_path / "runs.json"
    f.write_text(json.dumps([row("CGG", 1, 1.0, 40.0, 100.0), row("CGG", 1, 20.0, 40.4, 101.0)]))
    out = subprocess.run([sys.executable, SCRIPT, "--table-from", str(f)], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "| CGG | 1 | 40.0 / 40.4 | 100.0 / 101.0 | 1.0% | 1.0% |" in out.stdout


def test_table_from_bad_file_names_it(tmp_path):
    f = tmp_path / "broken.json"
    f.write_text("{not json")
    out = subprocess.run([sys.executable, SCRIPT, "--table-from", str(f)], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode != 0
    assert str(f) in out.stderr and len(out.stderr.strip().splitlines()) == 1
