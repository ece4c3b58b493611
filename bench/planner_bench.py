#!/usr/bin/python3
"""Planner benchmark: the cost of a plan around temporary obstacles (other robots), on the
same cases with ``obstacle_search="astar"`` (scipy's Dijkstra in the small box around the
obstacles, then, when the box cannot settle the plan, the C++ A*) and with ``"window"`` (the
box, then scipy's Dijkstra in growing windows, possibly the whole map).

A case is a start and a goal drawn among the free cells of a shipped map, with 1-3 robots
standing on or near the obstacle-free optimal path and, in a third of the cases, one on the
goal vertex (which moves the goal): what a patrol team makes the planner do. Both planners
share one grid, and every goal's obstacle-free navigation function is computed before the
timing (as it is cached in a run), so the figures are the searches with obstacles alone:
CPU time of this thread per plan, median, 90th percentile and mean, and the cells each
search touched (A*: cells expanded). The two planners' path costs must agree (checked).

    bench/planner_bench.py [--maps cumberland broughton] [--cases 300] [--seed 1]
"""
import argparse
import datetime
import math
import os
import platform
import statistics
import sys
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for sub in ("src/patrolling_sim/src", "src/spqrel_nav_lite/src"):
    sys.path.insert(0, os.path.join(ROOT, sub))
from spqrel_nav_lite.mapio import load_map  # noqa: E402
from spqrel_nav_lite.planner import GlobalPlanner, PlanningError  # noqa: E402
from spqrel_nav_lite.planner_grid import PlannerGrid  # noqa: E402


def cases(p, rng, n):
    """[(start, goal, obstacle points)] with an obstacle-free path from start to goal."""
    free = np.argwhere(~p.lethal)
    out = []
    while len(out) < n:
        (aj, ai), (bj, bi) = free[rng.integers(len(free), size=2)]
        start, goal = p.cell_center(ai, aj), p.cell_center(bi, bj)
        p.clear_obstacles()
        try:
            base = p.plan(start, goal)
        except PlanningError:
            continue
        pts = base[rng.integers(len(base), size=rng.integers(1, 4))] + \
            rng.normal(0.0, 0.3, (1, 2))
        if rng.random() < 1 / 3:
            pts = np.vstack([pts, np.array(goal) + rng.normal(0.0, 0.1, (1, 2))])
        p.set_obstacles(pts)
        si, sj = p.cell(*start)
        if p.blocked_mask()[sj, si]:
            continue
        out.append((start, goal, pts))
    p.clear_obstacles()
    return out


def run(p, todo):
    """(CPU ms per plan, path costs, searches, cells touched) of planning every case."""
    ms, costs = [], []
    s0, e0 = p.searches, p.astar_expanded
    for start, goal, pts in todo:
        p.clear_obstacles()
        p.plan(start, goal)                 # the obstacle-free field, as in a run
        p.set_obstacles(pts)
        t = time.thread_time()
        try:
            p.plan(start, goal)
            c = p.path_cost(start)
        except PlanningError:
            c = math.inf
        ms.append(1000 * (time.thread_time() - t))
        costs.append(c)
    return ms, np.array(costs), p.searches - s0, p.astar_expanded - e0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=["cumberland", "broughton"])
    ap.add_argument("--cases", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    if a.cases < 1:
        ap.error("--cases must be >= 1")
    print(f"Machine: {platform.node()}, {os.cpu_count()} cores, "
          f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; "
          f"{a.cases} cases per map, seed {a.seed}\n")
    print("| map | grid | search | median (ms) | p90 (ms) | mean (ms) | searches | A* cells "
          "expanded per search |")
    print("|---|---|---|---|---|---|---|---|")
    for name in a.maps:
        path = os.path.join(ROOT, "maps", name, f"{name}.yaml")
        if not os.path.isfile(path):
            sys.exit(f"planner_bench: --maps: no map {path}")
        m = load_map(path)
        grid = PlannerGrid(m, cache_bytes=4 << 30)
        astar = GlobalPlanner(m, obstacle_margin=0.2, grid=grid, obstacle_search="astar")
        if not astar.astar:
            sys.exit("planner_bench: the C++ A* is not built (catkin_make)")
        window = GlobalPlanner(m, obstacle_margin=0.2, grid=grid, obstacle_search="window")
        todo = cases(window, np.random.default_rng(a.seed), a.cases)
        got = {}
        for label, p in (("window", window), ("astar", astar)):
            got[label] = run(p, todo)
        same = np.isclose(got["window"][1], got["astar"][1], rtol=1e-5) | \
            (np.isinf(got["window"][1]) & np.isinf(got["astar"][1]))
        if not same.all():
            sys.exit(f"planner_bench: {name}: path costs differ in {int((~same).sum())} cases")
        for label in ("window", "astar"):
            ms, _, searches, cells = got[label]
            ms_sorted = sorted(ms)
            per = f"{cells / max(1, searches):.0f}" if label == "astar" else "-"
            print(f"| {name} | {grid.w} x {grid.h} | {label} | {statistics.median(ms):.2f} | "
                  f"{ms_sorted[int(0.9 * (len(ms) - 1))]:.2f} | {statistics.mean(ms):.2f} | "
                  f"{searches} | {per} |")


if __name__ == "__main__":
    main()
