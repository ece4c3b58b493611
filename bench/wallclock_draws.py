#!/usr/bin/python3
"""What the original's wall-clock reseeding changes (docs/fidelity.md, "Ties").

The original's RAND, CR, HCR, HPCC, GBS and SEBS agents call ``srand(time(NULL))`` before
the draw that picks a random neighbour or breaks a tie; this project draws from each robot's
seeded generator. This script runs graph mode twice per seed, once with the seeded draws
(the default) and once with the original's draws emulated at a given pace
(``original_draws_pace``, ``original_draws_epoch``:
:mod:`patrolling_sim.algorithms.wallclock`), on every map and team size asked for, and
prints per cell the means over the seeds and the emulated / seeded ratio of the average
idleness, the maximum idleness and the visits.

``--check`` first runs the world of the original's reference runs (grid, 4 robots at
vertices 0, 13, 20, 11, straight-line travel, 600 s, the original's x20) for RAND, whose
reference average idleness is 25.3 s (tests/unit/data/original_runs/).

Usage:
    bench/wallclock_draws.py [--maps all] [--robots 2 4 8] [--algs RAND CR ...]
                             [--seeds 5] [--duration 1800] [--pace 20] [--check]
                             [--json FILE]
"""
import argparse
import json
import os
import statistics
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
sys.path.insert(0, os.path.join(ROOT, "src", "spqrel_nav_lite", "src"))
from patrolling_sim.algorithms.wallclock import EPOCH_PARAM, PACE_PARAM  # noqa: E402
from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402

#: the algorithms whose original agents reseed from the wall clock before a draw
ALGS = ("RAND", "CR", "HCR", "HPCC", "GBS", "SEBS")


def epoch_of(seed: int) -> int:
    """The emulated wall-clock second at the clock's zero for run ``seed`` (any value; a
    different one per seed, as a real clock gives)."""
    return 1_700_000_000 + 7919 * seed


def run(map_name, robots, alg, seed, duration, pace, **world):
    """(avg idleness, max idleness, visits, never-visited vertices) of one graph-mode run;
    ``pace`` 0: seeded draws."""
    params = {PACE_PARAM: pace, EPOCH_PARAM: epoch_of(seed)} if pace else {}
    s = GraphSimulator(GraphSimConfig(map=map_name, robots=robots, alg=alg, seed=seed,
                                      duration=duration, params=params, **world)
                       ).run(write=False)
    never = sum(1 for v in s.per_vertex if v.visits < 0)   # -1: never visited
    return s.global_avg, s.global_max, s.total_visits, never


def cell(map_name, robots, alg, seeds, duration, pace, **world):
    """Means over ``seeds`` with seeded and with emulated draws."""
    out = {}
    for label, p in (("seeded", 0), ("original", pace)):
        rows = [run(map_name, robots, alg, s, duration, p, **world) for s in range(seeds)]
        out[label] = {k: statistics.fmean(r[i] for r in rows)
                      for i, k in enumerate(("avg", "max", "visits"))}
        out[label]["never"] = sum(1 for r in rows if r[3])
    return out


def _ratio(a, b):
    return a / b if b else float("nan")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--maps", nargs="+", default=["all"])
    ap.add_argument("--robots", nargs="+", type=int, default=[2, 4, 8])
    ap.add_argument("--algs", nargs="+", default=list(ALGS))
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--duration", type=float, default=1800.0)
    ap.add_argument("--pace", type=float, default=20.0,
                    help="emulated original's pace, sim s per wall s (default 20)")
    ap.add_argument("--check", action="store_true",
                    help="first the world of the original's reference runs (grid, RAND)")
    ap.add_argument("--json", help="also write the figures here")
    a = ap.parse_args(argv)
    maps = paths.available_maps() if a.maps == ["all"] else a.maps
    result = {"pace": a.pace, "duration": a.duration, "seeds": a.seeds, "cells": []}
    if a.check:
        c = cell("grid", 4, "RAND", a.seeds, 600.0, a.pace, travel="euclidean",
                 initpos="vertices:0,13,20,11")
        result["check"] = c
        print(f"reference world, RAND: avg idleness seeded {c['seeded']['avg']:.1f} s, "
              f"original's draws emulated {c['original']['avg']:.1f} s (the original's "
              "reference runs: 25.3 s)", flush=True)
    print("| map | robots | alg | avg idleness seeded / emulated (ratio) | max idleness "
          "seeded / emulated (ratio) | visits (ratio) | seeds with a never-visited vertex |")
    print("|---|---|---|---|---|---|---|")
    for m in maps:
        for n in a.robots:
            for alg in a.algs:
                c = cell(m, n, alg, a.seeds, a.duration, a.pace)
                s, o = c["seeded"], c["original"]
                result["cells"].append({"map": m, "robots": n, "alg": alg, **c})
                print(f"| {m} | {n} | {alg} | {s['avg']:.1f} / {o['avg']:.1f} "
                      f"({_ratio(o['avg'], s['avg']):.2f}) | {s['max']:.0f} / {o['max']:.0f} "
                      f"({_ratio(o['max'], s['max']):.2f}) | "
                      f"{_ratio(o['visits'], s['visits']):.2f} | {s['never']} / {o['never']} |",
                      flush=True)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(result, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
