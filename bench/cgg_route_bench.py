#!/usr/bin/python3
"""CPU time of CGG's route construction per shipped map (the original's construction:
Hamiltonian walk, else longest cycle / longest path with detours, see docs/fidelity.md).

Each map is built ``--repeat`` times on a fresh graph object (no cache); the figure is the
process CPU time (user + system, not wall time, so a loaded machine does not inflate it)
per build. Prints a Markdown table (and writes it to ``--out`` if given).

Usage:
    bench/cgg_route_bench.py [--maps ...] [--repeat 3] [--out FILE]
"""
import argparse
import datetime
import os
import platform
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))

from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.algorithms.cgg import original_cyclic_route  # noqa: E402
from patrolling_sim.model.graph import PatrolGraph  # noqa: E402
from patrolling_sim.planning.routes import route_cost  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--maps", nargs="+", default=paths.available_maps())
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--out")
    a = p.parse_args()
    if a.repeat < 1:
        p.error("--repeat: must be >= 1")
    lines = [f"CGG route construction, CPU s per build (mean of {a.repeat}); "
             f"{platform.node()}, {datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC, "
             f"load avg {os.getloadavg()[0]:.2f}", "",
             "| map | vertices | route source | entries | cost (px) | CPU s |",
             "|---|---|---|---|---|---|"]
    for m in a.maps:
        gpath = paths.map_files(m)[1]
        cpu = 0.0
        for _ in range(a.repeat):
            g = PatrolGraph.load(gpath)
            t0 = time.process_time()
            route, source = original_cyclic_route(g)
            cpu += time.process_time() - t0
        lines.append(f"| {m} | {g.n} | {source} | {len(route)} | "
                     f"{route_cost(g, route):.0f} | {cpu / a.repeat:.3f} |")
    text = "\n".join(lines)
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
