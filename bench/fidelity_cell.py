#!/usr/bin/python3
"""One cell of the fidelity matrix up close (docs/fidelity_matrix.md): the stored runs of the
original's agents for a map, team size and algorithm, run by run, beside this project's graph
mode in the same world over many seeds, so that a cell out of tolerance can be looked into
before its difference is documented (tests/unit/data/original_matrix/known_differences.csv).

Per run of the original: pace reached (sim s per wall s), load average at its start, average
and maximum idleness, visits, the fewest visit reports of a vertex (0: a vertex never
visited). Then graph mode per seed (the matrix's world: default start positions, straight
lines at 1 m/s, no interference, no delay or loss) with the same figures, and both means with
their standard errors and the graph mode's difference from the original's mean against the
matrix's tolerances (avg 10 %, max 25 %, visits 10 %).

``--go-time`` sets how long graph mode's agents' clock ran before GO (default: the
matrix's, tests/unit/original_matrix.py ``GO_TIME``). ``--goal-wait`` sets graph mode's goal
wait (the matrix uses 0; about 0.1 s stands for the abstract world's reaction time and
arrival step). ``--pace P`` emulates the original's
wall-clock reseeding of its random draws at pace P (the algorithms that draw:
bench/wallclock_draws.py); ``--pace orig`` takes the mean pace of the original's runs.

Usage:
    bench/fidelity_cell.py MAP ROBOTS ALG [--seeds 0-9 | --seeds 0 1 2] [--go-time S]
                           [--goal-wait 0] [--pace P|orig] [--duration 1800] [--runs CSV]
"""
import argparse
import os
import statistics
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "unit"))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
sys.path.insert(0, os.path.join(ROOT, "src", "spqrel_nav_lite", "src"))
import original_matrix as om  # noqa: E402
from patrolling_sim.algorithms.wallclock import EPOCH_PARAM, PACE_PARAM  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402
from wallclock_draws import epoch_of  # noqa: E402  (bench/, beside this script)


def parse_seeds(words):
    """Seeds from ``['0-9']`` or ``['0', '1', '2']``; raises ValueError on anything else."""
    out = []
    for w in words:
        lo, sep, hi = w.partition("-")
        if sep:
            out.extend(range(int(lo), int(hi) + 1))
        else:
            out.append(int(w))
    if not out:
        raise ValueError("no seeds")
    return out


def graph_run(map_name, robots, alg, seed, duration, goal_wait, pace, go_time):
    """(avg, max, visits, fewest visit reports of a vertex) of one graph-mode run."""
    cfg = om.graph_config(map_name, robots, alg, seed, duration, go_time=go_time)
    cfg.gwait = goal_wait
    if pace:
        cfg.params = dict(cfg.params or {}, **{PACE_PARAM: pace, EPOCH_PARAM: epoch_of(seed)})
    s = GraphSimulator(cfg).run(write=False)
    fewest = min(v.visits + 1 for v in s.per_vertex)   # idleness samples + the first visit
    return s.global_avg, s.global_max, s.total_visits, fewest


def _mean_se(xs):
    m = statistics.fmean(xs)
    se = statistics.stdev(xs) / len(xs) ** 0.5 if len(xs) > 1 else float("nan")
    return m, se


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("map")
    ap.add_argument("robots", type=int)
    ap.add_argument("alg")
    ap.add_argument("--seeds", nargs="+", default=["0-9"])
    ap.add_argument("--goal-wait", type=float, default=0.0)
    ap.add_argument("--go-time", type=float, default=None,
                    help="s graph mode's agents' clock ran before GO (default: the matrix's)")
    ap.add_argument("--pace", default=None, help="emulate the original's wall-clock draws at "
                    "this pace, or 'orig': its runs' mean pace")
    ap.add_argument("--duration", type=float, default=1800.0)
    ap.add_argument("--runs", default=om.RUNS, help="summary CSV of the original's runs")
    a = ap.parse_args(argv)
    try:
        seeds = parse_seeds(a.seeds)
    except ValueError:
        ap.error(f"--seeds: expected numbers or ranges such as 0-9, got {' '.join(a.seeds)}")
    if not os.path.isfile(a.runs):
        ap.error(f"--runs: no such file: {a.runs}")
    rows = [r for r in om.read_rows(a.runs) if r["agents"] == "original" and r["map"] == a.map
            and r["robots"] == a.robots and r["algorithm"] == a.alg
            and r["duration"] == a.duration]
    used = [r for r in rows if om.complete(r) and not om.crashed(r)]
    if not used:
        print(f"fidelity_cell.py: no complete run of the original for {a.map} {a.robots} "
              f"{a.alg} in {a.runs}", file=sys.stderr)
        return 1
    paces = [r["sim_duration"] / r["real_duration"] for r in used]
    pace = None
    if a.pace == "orig":
        pace = statistics.fmean(paces)
    elif a.pace is not None:
        try:
            pace = float(a.pace)
        except ValueError:
            ap.error(f"--pace: expected a number or 'orig', got {a.pace}")
    print(f"{a.map}, {a.robots} robots, {a.alg}: original's runs (pace, load, avg, max, "
          "visits, fewest visits of a vertex)")
    orig = []
    for r, p in zip(used, paces):
        fig = (r["avg_idleness"], r["max_idleness"], r["visits"], min(r["visit_counts"]))
        orig.append(fig)
        print(f"  run {r['run']:>2}: x{p:4.1f} load {r['load1']:5.1f}  {fig[0]:7.2f} "
              f"{fig[1]:7.1f} {fig[2]:6d} {fig[3]:4d}")
    left = len(rows) - len(used)
    if left:
        print(f"  ({left} run(s) left out: incomplete, or an agent's process ended)")
    go = a.go_time if a.go_time is not None else om.GO_TIME
    print(f"graph mode (goal wait {a.goal_wait} s, clock started {go:g} s before GO"
          + (f", original's draws at x{pace:.1f}" if pace else "") + ")")
    ours = []
    for s in seeds:
        fig = graph_run(a.map, a.robots, a.alg, s, a.duration, a.goal_wait, pace, a.go_time)
        ours.append(fig)
        print(f"  seed {s:>2}:                  {fig[0]:7.2f} {fig[1]:7.1f} {fig[2]:6d} "
              f"{fig[3]:4d}", flush=True)
    print("metric   original (mean +- se)   graph mode (mean +- se)   difference  tolerance")
    for k, m in enumerate(om.METRICS):
        om_, ose = _mean_se([f[k] for f in orig])
        gm, gse = _mean_se([f[k] for f in ours])
        rel = (gm - om_) / om_ if om_ else float("inf")
        ok = "within" if abs(rel) <= om.TOL[m] else "OUT"
        print(f"{m:7s} {om_:9.2f} +- {ose:6.2f}      {gm:9.2f} +- {gse:6.2f}        "
              f"{rel:+6.1%}    {om.TOL[m]:.0%} {ok}")
    starve = sum(1 for f in orig if f[3] == 0), sum(1 for f in ours if f[3] == 0)
    print(f"runs with a vertex never visited: original {starve[0]} of {len(orig)}, "
          f"graph mode {starve[1]} of {len(ours)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
