#!/usr/bin/python3
"""ROS-mode column of docs/fidelity.md: our agents + monitor in the abstract world (runner
``--nav abstract``, grid, 4 robots at vertices 0, 13, 20, 11, 600 sim s after GO), against
the original's reference runs in tests/unit/data/original_runs/.

Prints a Markdown table: per algorithm the original's mean avg / max / visits, ours (mean
over ``--runs`` runs, seeds 0..runs-1) and the differences in %, plus the agents' mean
turnaround (sim s from a SUCCEEDED to the next goal, docs/abstract_world.md). Every run must
end on TIMEOUT after the full duration; a run that does not is reported, not averaged.
Algorithms without reference runs (this project's own, e.g. CGG_TSP, MSP_BAL) are measured
the same way, with "(ours only)" in the original's column.

Usage:
    bench/fidelity_ros.py [--algs CR CGG ...] [--runs 1] [--speedup 30]
                          [--processes shared|separate] [--json out.json]
"""
import argparse
import json
import os
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "ros"))
sys.path.insert(0, os.path.join(ROOT, "tests", "unit"))
from abstract_runs import SPEEDUP, mean_figures, run_abstract  # noqa: E402
import fidelity_common as fc  # noqa: E402


def pct(ours, theirs):
    return f"{(ours - theirs) / theirs:+.0%}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--algs", nargs="+", help="default: every algorithm with reference runs")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--speedup", type=float, default=SPEEDUP)
    ap.add_argument("--processes", default="shared", choices=("shared", "separate"))
    ap.add_argument("--json")
    a = ap.parse_args()
    if a.runs < 1:
        ap.error(f"argument --runs: must be >= 1, got {a.runs}")
    algs = a.algs or fc.reference_algorithms()
    duration = fc.reference_duration()
    print(f"ROS mode, abstract world, grid, 4 robots, {duration:.0f} s after GO, x{a.speedup:g}, "
          f"--processes {a.processes}; ours = mean of {a.runs} run(s), seeds 0..{a.runs - 1}."
          "\n")
    print("| alg | original avg / max / visits | ours (ROS) avg / max / visits | "
          "diff avg / max / visits | turnaround s |")
    print("|---|---|---|---|---|")
    raw = {}
    for alg in algs:
        ref = mean_figures(fc.reference_figures(alg)) \
            if alg in fc.reference_algorithms() else None
        ok, notes = [], []
        for seed in range(a.runs):
            with tempfile.TemporaryDirectory(prefix=f"fidelity_ros_{alg}_") as d:
                r = run_abstract(alg, seed, d, processes=a.processes, speedup=a.speedup,
                                 duration=duration)
            if r.exit_code == 0 and r.complete(duration):
                ok.append(r)
            else:
                notes.append(f"seed {seed}: exit {r.exit_code}, "
                             f"{r.info['termination'] if r.info else 'no info.csv'}")
        raw[alg] = dict(original=ref, ours=[dict(figures=r.figures(), turnaround=r.turnaround)
                                            for r in ok], failed=notes)
        ref_s = f"{ref[0]:.1f} / {ref[1]:.1f} / {ref[2]:.0f}" if ref else "(ours only)"
        if not ok:
            print(f"| {alg} | {ref_s} | no complete run ({'; '.join(notes)}) | | |",
                  flush=True)
            continue
        ours = mean_figures([r.figures() for r in ok])
        turn = [r.turnaround for r in ok if r.turnaround is not None]
        turn_s = f"{sum(turn) / len(turn):.3f}" if turn else "-"
        diff_s = (f"{pct(ours[0], ref[0])} / {pct(ours[1], ref[1])} / {pct(ours[2], ref[2])}"
                  if ref else "-")
        print(f"| {alg} | {ref_s} | {ours[0]:.1f} / {ours[1]:.1f} / {ours[2]:.0f} | "
              f"{diff_s} | {turn_s} |" + (f" ({'; '.join(notes)})" if notes else ""),
              flush=True)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(raw, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
