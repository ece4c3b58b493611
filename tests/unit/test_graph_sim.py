"""Graph-level simulator: files, determinism, stopping rules, message delay and loss."""
import os
import subprocess
import sys

import pytest

from patrolling_sim.errors import PatrolInputError
from patrolling_sim.graph_sim import GraphSimConfig, GraphSimulator, claim_prefix
from patrolling_sim.results import parse_info_line

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def run(tmp_path, **kw):
    cfg = GraphSimConfig(results_dir=str(tmp_path), **kw)
    sim = GraphSimulator(cfg)
    stats = sim.run()
    return sim, stats


def rows(prefix):
    with open(prefix + "_idleness.csv") as f:
        lines = f.read().splitlines()
    assert lines[0] == "Time;Robot;Node;Idleness;Interferences"
    return [l.split(";") for l in lines[1:]]


def test_files_and_metrics_agree(tmp_path):
    sim, s = run(tmp_path, map="grid", robots=2, alg="CR", duration=1000, seed=1)
    for suf in ("idleness.csv", "timeresults.csv", "results.txt", "info.csv"):
        assert os.path.isfile(f"{sim.prefix}_{suf}"), suf
    assert "/grid_2/CR/" in sim.prefix
    info = parse_info_line(open(sim.prefix + "_info.csv").read())
    assert info["nav_module"] == "graph" and info["termination"] == "TIMEOUT"
    assert info["sim_duration"] == pytest.approx(1000.0)
    samples = [float(r[3]) for r in rows(sim.prefix)]
    assert len(samples) == s.n_samples > 100
    assert info["idl_avg"] == pytest.approx(sum(samples) / len(samples), abs=0.06)
    assert info["idl_max"] == pytest.approx(max(samples), abs=0.06)
    assert info["complete_cycles"] == s.cycles >= 3
    # grid edges are all 5.7 m: at 1 m/s a robot reports a vertex every 5.7 s
    times = sorted(float(r[0]) for r in rows(sim.prefix) if r[1] == "0")
    gaps = {round(b - a, 1) for a, b in zip(times, times[1:])}
    assert gaps <= {5.7, 11.4, 17.1, 22.8}


def test_deterministic(tmp_path):
    a, _ = run(tmp_path / "a", map="example", robots=3, alg="SEBS", duration=800, seed=4)
    b, _ = run(tmp_path / "b", map="example", robots=3, alg="SEBS", duration=800, seed=4)
    c, _ = run(tmp_path / "c", map="example", robots=3, alg="SEBS", duration=800, seed=5)
    assert rows(a.prefix) == rows(b.prefix)
    assert rows(a.prefix) != rows(c.prefix)


def test_stop_after_cycles(tmp_path):
    sim, s = run(tmp_path, map="grid", robots=4, alg="CGG", duration=0, cycles=3)
    assert s.cycles == 3 and sim.termination == "CYCLES"
    assert parse_info_line(open(sim.prefix + "_info.csv").read())["termination"] == "CYCLES"
    blocks = open(sim.prefix + "_results.txt").read().count("Complete Patrol Cycles:")
    assert blocks == 3


def test_cgg_beats_random_on_worst_idleness(tmp_path):
    _, cgg = run(tmp_path, map="grid", robots=4, alg="CGG", duration=3000)
    _, rnd = run(tmp_path, map="grid", robots=4, alg="RAND", duration=3000)
    assert cgg.global_max < rnd.global_max / 2


def test_loss_and_delay(tmp_path):
    sim, _ = run(tmp_path, map="grid", robots=3, alg="GBS", duration=600, loss=0.5, seed=2)
    assert sim.messages_sent > 100
    assert 0.35 < sim.messages_lost / sim.messages_sent < 0.65
    sim0, _ = run(tmp_path, map="grid", robots=3, alg="GBS", duration=600, loss=0.0, seed=2)
    assert sim0.messages_lost == 0


def test_goal_wait_slows_visits(tmp_path):
    _, fast = run(tmp_path, map="grid", robots=1, alg="CR", duration=1000)
    _, slow = run(tmp_path, map="grid", robots=1, alg="CR", duration=1000, gwait=5.7)
    # reports = counted visits + the 25 uncounted first visits
    assert slow.total_visits + 25 == pytest.approx((fast.total_visits + 25) / 2, rel=0.03)


@pytest.mark.parametrize("kw,needle", [
    (dict(alg="NOPE"), "argument --alg: unknown algorithm 'NOPE'"),
    (dict(robots=0), "argument --robots"),
    (dict(duration=0), "argument --duration"),
    (dict(loss=1.0), "argument --loss"),
    (dict(map="atlantis"), "atlantis"),
])
def test_bad_config(kw, needle, tmp_path):
    with pytest.raises(PatrolInputError) as e:
        GraphSimConfig(results_dir=str(tmp_path), **kw).validate()
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_claim_prefix_unique(tmp_path):
    p = str(tmp_path / "x" / "20260101_000000")
    assert claim_prefix(p) == p
    assert claim_prefix(p) == p + "_1"


def test_cli(tmp_path):
    out = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_sim.py"),
                          "--map", "1r5", "--robots", "2", "--alg", "MSP", "--duration", "300",
                          "--results-dir", str(tmp_path), "--repeat", "2", "--quiet"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("results: ") == 2
    bad = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_sim.py"),
                          "--robots", "x"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    bad = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_sim.py"),
                          "--alg", "XX", "--results-dir", str(tmp_path)],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "unknown algorithm 'XX'" in bad.stderr


@pytest.mark.parametrize("alg", ["RAND", "CR", "HCR", "HPCC", "CGG", "MSP", "GBS", "SEBS",
                                 "CBLS", "DTAG", "DTAP"])
@pytest.mark.parametrize("mapname,n", [("1r5", 3), ("1r5", 8), ("cumberland", 8)])
def test_every_algorithm_runs_crowded_teams(alg, mapname, n, tmp_path):
    """Many robots on few vertices, with delay and loss: time advances, every vertex is
    visited, the run ends (a zero-time decision loop would hang or explode here)."""
    sim, s = run(tmp_path, map=mapname, robots=n, alg=alg, duration=600, comm_delay=0.5,
                 loss=0.1, seed=1)
    assert sim.termination == "TIMEOUT"
    assert s.n_samples > 0
    assert all(v >= 0 for v in sim.monitor.visits), f"{alg} left vertices unvisited"
