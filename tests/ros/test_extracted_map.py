"""A full-stack experiment on a map whose graph was extracted automatically:
grid's image -> graph_tool.py extract -> 4 robots, CGG, fake localisation, optimised start,
300 s at speedup 8 -- every vertex visited (and revisited)."""
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "unit"))

from test_experiments import ROOT, check_files, finish, master_ports_closed, own_processes, \
    prefixes, start  # noqa: E402
from test_extract import TOOL  # noqa: E402


def test_cgg_four_robots_on_extracted_grid(tmp_path):
    mdir = tmp_path / "gridx"
    mdir.mkdir()
    for f in ("grid.yaml", "grid.pgm"):
        shutil.copy(os.path.join(ROOT, "maps", "grid", f), mdir / f)
    r = subprocess.run(["/usr/bin/python3", TOOL, "extract", str(mdir / "grid.yaml")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    n_vertices = int(open(mdir / "grid.graph").read().split()[0])
    assert n_vertices != 25           # not the hand-made graph
    p = start(["--map", str(mdir / "grid.yaml"), "--robots", "4", "--alg", "CGG",
               "--loc", "fake_localization", "--initpos", "optimised", "--timeout", "300",
               "--speedup", "8"], tmp_path)
    rc, out = finish(p, 900)
    assert rc == 0, out[-3000:]
    (prefix,) = prefixes(tmp_path)
    info, rows = check_files(prefix)
    assert info["termination"] == "TIMEOUT" and info["algorithm"] == "CGG", out[-2000:]
    assert 299.0 <= info["sim_duration"] <= 310.0
    assert info["complete_cycles"] >= 1, out[-2000:]
    visited = {int(r.split(";")[2]) for r in rows}
    assert visited == set(range(n_vertices)), f"never revisited: {set(range(n_vertices)) - visited}"
    poses = open(prefix + "_start_poses.txt").read().splitlines()
    assert poses[0] == "# start poses: --initpos optimised" and len(poses) == 2 + 4
    assert master_ports_closed(out)
    assert own_processes(prefix) == []
