#!/usr/bin/python3
"""Start-position benchmark: worst idleness with ``--initpos optimised`` against the default
start, in graph mode (straight-line travel at 1 m/s, goal wait 0, no interference).

For each map, team size and algorithm: one run of ``--duration`` simulated seconds with each
start; prints a Markdown table (and writes it to ``--out``). For CGG it also prints L/(N v),
the ideal worst idleness of N robots evenly spread on a closed walk of length L.

Usage:
    bench/startpos_bench.py [--maps ...] [--robots 2 4 8] [--algs CGG MSP] [--seeds 1 2 3]
                            [--duration 3000] [--out bench/notes/startpos.md]

Each robot starts after a random U(0, 1) s delay (seeded), so single runs differ by up to
about a second; ``--seeds`` averages over several.
"""
import argparse
import datetime
import os
import platform
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))

from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
from patrolling_sim.model.graph import PatrolGraph  # noqa: E402
from patrolling_sim.startpos.optimised import probe_route  # noqa: E402
from patrolling_sim.planning.routes import route_cost  # noqa: E402


def worst(map_name, n, alg, initpos, duration, pg, seeds):
    """Mean over ``seeds`` of the worst idleness (the seed sets the U(0, 1) s start delays)."""
    out = []
    for seed in seeds:
        cfg = GraphSimConfig(map=map_name, robots=n, alg=alg, duration=duration, seed=seed,
                             initpos=initpos, travel="euclidean", interference=False)
        value = GraphSimulator(cfg, pgraph=pg).run(write=False).global_max
        if value is None:   # no vertex visited twice yet: no idleness sample
            sys.exit(f"startpos_bench: error: argument --duration: {duration:g} s gave no "
                     f"idleness sample ({map_name}, {n} robots, {alg}, {initpos} start, seed "
                     f"{seed}); give a longer duration")
        out.append(value)
    return sum(out) / len(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--maps", nargs="*", default=None)
    ap.add_argument("--robots", nargs="*", type=int, default=[2, 4, 8])
    ap.add_argument("--algs", nargs="*", default=["CGG", "CGG_TSP", "MSP"])
    ap.add_argument("--duration", type=float, default=3000.0)
    ap.add_argument("--seeds", nargs="*", type=int, default=[1])
    ap.add_argument("--out")
    a = ap.parse_args()
    import logging
    logging.disable(logging.WARNING)
    rows = ["| map | N | alg | worst idleness default (s) | optimised (s) | L/(N v) (s) |",
            "|---|---|---|---|---|---|"]
    for m in a.maps or paths.available_maps():
        for n in a.robots:
            for alg in a.algs:
                pg = PatrolGraph.load(paths.map_files(m)[1])
                d = worst(m, n, alg, "default", a.duration, pg, a.seeds)
                pg = PatrolGraph.load(paths.map_files(m)[1])
                o = worst(m, n, alg, "optimised", a.duration, pg, a.seeds)
                ideal = ""
                if alg in ("CGG", "CGG_TSP"):
                    L = route_cost(pg, probe_route(pg, alg, n, m, 0)) * pg.resolution
                    ideal = f"{L / n:.1f}"
                row = f"| {m} | {n} | {alg} | {d:.1f} | {o:.1f} | {ideal} |"
                print(row, flush=True)
                rows.append(row)
    head = (f"Start positions, graph mode, {a.duration:g} s, mean over seeds "
            f"{' '.join(map(str, a.seeds))}, straight lines at 1 m/s, goal wait 0, no interference "
            f"({platform.node()}, {datetime.date.today()}; bench/startpos_bench.py)\n\n")
    if a.out:
        with open(a.out, "w", encoding="utf-8") as f:
            f.write(head + "\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
