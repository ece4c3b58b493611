#!/usr/bin/python3
"""Plan store benchmark (spqrel_nav_lite.plan_store, docs/navigation.md "Plan store").

For each map: the obstacle-free navigation function of every patrol vertex (the goals a
patrol run sends, snapped to the planner grid as move_base snaps them), obtained three ways,
each in a fresh planner grid as a new navigation process would:

- ``search``: no store: one whole-map Dijkstra per vertex (what every navigation process of
  every run paid before the store);
- ``cold``: an empty store: the same searches plus writing each result to disk;
- ``warm``: the filled store: each function read back (memory-mapped) instead of searched.

Reports the process CPU time per vertex and in all (``time.process_time``, so what else runs
on the machine matters little), the store's size on disk, and checks that every stored
function equals the searched one bit for bit. The store lives in a temporary folder.

Usage: bench/plan_store_bench.py [--maps broughton cumberland grid] [--repeat 3]
"""
import argparse
import os
import platform
import shutil
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for p in ("patrolling_sim", "spqrel_nav_lite"):
    sys.path.insert(0, os.path.join(ROOT, "src", p, "src"))
from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.model.graph import load_graph  # noqa: E402
from spqrel_nav_lite.mapio import load_map  # noqa: E402
from spqrel_nav_lite.planner import GlobalPlanner  # noqa: E402
from spqrel_nav_lite.planner_grid import PlannerGrid  # noqa: E402


def goal_cells(omap, graph_path):
    """(goal cell of every patrol vertex, as move_base's planner checks it (0.4 m tolerance),
    the planner grid's width and height)."""
    G = load_graph(graph_path, warn=False)
    probe = GlobalPlanner(omap)
    cells = []
    for v in sorted(G.nodes):
        x, y = G.nodes[v]["pos"]
        i, j = probe.check_goal(x, y, 0.4)
        cells.append(j * probe.w + i)
    return cells, probe.w, probe.h


def one_pass(omap, cells, store):
    t0 = time.process_time()
    grid = PlannerGrid(omap, store_root=store)
    t1 = time.process_time()
    fields = [grid.free_navigation_function(g) for g in cells]
    t2 = time.process_time()
    searched = sum(f[2] for f in fields)
    return t1 - t0, t2 - t1, searched, [(f[0], f[1]) for f in fields]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=["broughton", "cumberland", "grid"])
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    if a.repeat < 1:
        ap.error(f"argument --repeat: must be >= 1, got {a.repeat}")
    print(f"# plan store, {platform.node()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())},"
          f" load {os.getloadavg()[0]:.2f}, best of {a.repeat}\n")
    print("| map | vertices | grid (cells) | grid build s | search: s per vertex / all | "
          "cold: s all | warm: s per vertex / all | store MB | identical |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in a.maps:
        yaml_path, graph_path = paths.map_files(name)
        omap = load_map(yaml_path)
        cells, w, h = goal_cells(omap, graph_path)
        cells = sorted(set(cells))
        best = {}
        same = True
        for _ in range(a.repeat):
            store = tempfile.mkdtemp(prefix="plan_store_bench_")
            try:
                build, search, n_s, ref = one_pass(omap, cells, None)
                _, cold, n_c, _ = one_pass(omap, cells, store)
                _, warm, n_w, got = one_pass(omap, cells, store)
                size = sum(os.path.getsize(os.path.join(d, f))
                           for d, _, fs in os.walk(store) for f in fs)
            finally:
                shutil.rmtree(store, ignore_errors=True)
            assert n_s == n_c == len(cells) and n_w == 0, (n_s, n_c, n_w)
            same &= all(np.array_equal(d1, d2) and np.array_equal(p1, p2)
                        for (d1, p1), (d2, p2) in zip(ref, got))
            for k, v in (("build", build), ("search", search), ("cold", cold), ("warm", warm)):
                best[k] = min(best.get(k, v), v)
        n = len(cells)
        print(f"| {name} | {n} | {w} x {h} | {best['build']:.2f} | "
              f"{best['search'] / n * 1000:.1f} ms / {best['search']:.2f} | {best['cold']:.2f} | "
              f"{best['warm'] / n * 1000:.2f} ms / {best['warm']:.3f} | {size / 2**20:.0f} | "
              f"{'yes' if same else 'NO'} |", flush=True)
        if not same:
            sys.exit(f"{name}: a stored navigation function differs from the searched one")


if __name__ == "__main__":
    main()
