#!/usr/bin/python3
"""Fidelity tables for docs/fidelity.md.

``maps``: graph mode on the larger maps (default cumberland, DIAG_labs, broughton), every
algorithm, several seeds, the shipped start poses; prints one Markdown table (mean over
seeds of avg idleness, max idleness and visits) and writes the raw figures as JSON.
``--src`` picks the patrolling_sim source tree to import, so the same script measures an
older checkout (the "before" table) and this one.

``grid``: graph mode in the reference runs' world (grid, 4 robots at vertices 0, 13, 20, 11,
600 s after GO, straight-line travel where the simulator offers it) against the original's
own result files under tests/unit/data/original_runs/ and, for DTAP and DTASSI, the runs of
the original's agents under tests/unit/data/original_agents_abstract_world/.

Usage:
    bench/fidelity_table.py maps [--src DIR] [--maps ...] [--robots 4] [--seeds 5]
                                 [--duration 3600] [--json out.json]
    bench/fidelity_table.py grid [--seeds 5] [--json out.json] [--ros-json ros.json]
    bench/fidelity_table.py diff BEFORE.json AFTER.json [--threshold 0.05]
"""
import argparse
import json
import math
import os
import statistics
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
DEFAULT_SRC = os.path.join(ROOT, "src", "patrolling_sim", "src")


def _import(src):
    if not os.path.isdir(os.path.join(src, "..", "..", "..", "maps")):
        # a source tree outside a checkout: read maps and params from this one
        os.environ.setdefault("PATROLLING_SIM_DATA", ROOT)
    sys.path.insert(0, os.path.abspath(src))
    # the navigation package beside it (the package imports its map loader and errors)
    sys.path.insert(1, os.path.abspath(os.path.join(src, "..", "..", "spqrel_nav_lite", "src")))
    from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402
    from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
    from patrolling_sim import algorithms  # noqa: E402
    return GraphSimConfig, GraphSimulator, algorithms


def original_names(algorithms):
    """The registered algorithms that carry one of the original's short names."""
    orig = ["RAND", "CR", "HCR", "HPCC", "CGG", "MSP", "GBS", "SEBS", "CBLS", "DTAG", "DTAP",
            "DTASSI"]
    return [a for a in orig if a in algorithms.REGISTRY]


def run_maps(a):
    GraphSimConfig, GraphSimulator, algorithms = _import(a.src)
    algs = a.algs or original_names(algorithms) + sorted(
        set(algorithms.REGISTRY) - set(original_names(algorithms)))
    raw = {}
    print(f"Graph mode, {a.robots} robots, {a.duration:.0f} s, seeds 0..{a.seeds - 1}, "
          f"shipped start poses, interference {'on' if a.interference else 'off'} (where the "
          f"simulator models it); source {a.src}; mean over seeds.\n")
    print("| alg | " + " | ".join(f"{m} avg / max / visits" for m in a.maps) + " |")
    print("|---|" + "---|" * len(a.maps))
    for alg in algs:
        cells = []
        for m in a.maps:
            runs = []
            for seed in range(a.seeds):
                kw = {}
                if "interference" in GraphSimConfig.__dataclass_fields__:
                    kw["interference"] = a.interference
                cfg = GraphSimConfig(map=m, robots=a.robots, alg=alg, duration=a.duration,
                                     seed=seed, **kw)
                s = GraphSimulator(cfg).run(write=False)
                runs.append((s.global_avg, s.global_max, s.total_visits))
            raw.setdefault(alg, {})[m] = runs
            cells.append(" / ".join(f"{statistics.mean(r[k] for r in runs):.1f}"
                                    for k in range(3)))
        print(f"| {alg} | " + " | ".join(cells) + " |", flush=True)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(dict(robots=a.robots, duration=a.duration, seeds=a.seeds, runs=raw), f)


def _ros_cell(v):
    """A ROS-mode cell from ``[avg, max, visits]`` or from bench/fidelity_ros.py's JSON entry
    (``{"ours": [{"figures": [avg, max, visits]}, ...], "failed": [...]}``)."""
    if isinstance(v, dict):
        runs = [r["figures"] for r in v.get("ours", [])]
        if not runs:
            return "no complete run"
        v = [statistics.mean(r[k] for r in runs) for k in range(3)]
        note = f" ({len(runs)} run{'s' if len(runs) > 1 else ''})"
    else:
        note = ""
    return f"{v[0]:.1f} / {v[1]:.1f} / {v[2]:.0f}{note}"


def run_grid(a):
    sys.path.insert(0, os.path.join(ROOT, "tests", "unit"))
    _import(a.src)
    import fidelity_common as fc  # noqa: E402
    algs = a.algs or fc.reference_algorithms() + [
        x for x in fc.names() if x not in fc.reference_algorithms()]
    a.ros = {}
    if a.ros_json:
        with open(a.ros_json, encoding="utf-8") as f:
            a.ros = {k: _ros_cell(v) for k, v in json.load(f).items()}
    raw = {}
    starts = fc.simulator(algs[0], 0).start_vertices
    print(f"grid, {fc.ROBOTS} robots at vertices {starts}, {fc.reference_duration():.0f} s "
          f"after GO; original = mean of its runs (tests/unit/data/original_runs; DTAP, DTASSI: "
          f"tests/unit/data/original_agents_abstract_world), ours = graph mode, mean of seeds "
          f"0..{a.seeds - 1}.\n")
    print("| alg | original avg / max / visits | ours (graph) avg / max / visits | "
          "ours (ROS, abstract world) |")
    print("|---|---|---|---|")
    for alg in algs:
        ref = fc.reference_figures(alg)
        ours = [fc.run_ours(alg, seed) for seed in range(a.seeds)]
        raw[alg] = dict(original=ref, ours=ours)
        mg = [statistics.mean(r[k] for r in ours) for k in range(3)]
        if ref:
            mo = [statistics.mean(r[k] for r in ref) for k in range(3)]
            orig = f"{mo[0]:.1f} / {mo[1]:.1f} / {mo[2]:.0f}" + (
                f" ({len(ref)} runs)" if len(ref) > 2 else "")
        else:
            orig = "(ours only)"
        print(f"| {alg} | {orig} | {mg[0]:.1f} / {mg[1]:.1f} / {mg[2]:.0f} | "
              f"{a.ros.get(alg, 'not measured')} |", flush=True)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(raw, f)


def run_diff(a):
    """Changes between two ``maps --json`` files: every mean that moved by more than
    ``--threshold`` (relative)."""
    with open(a.before, encoding="utf-8") as f:
        before = json.load(f)["runs"]
    with open(a.after, encoding="utf-8") as f:
        after = json.load(f)["runs"]
    names = ("avg", "max", "visits")
    print("| alg | map | metric | before | after | change | change / SE |")
    print("|---|---|---|---|---|---|---|")
    for alg in after:
        if alg not in before:
            continue
        for m in after[alg]:
            for k, metric in enumerate(names):
                b = statistics.mean(r[k] for r in before[alg][m])
                x = statistics.mean(r[k] for r in after[alg][m])
                if b and abs(x - b) > a.threshold * abs(b):
                    # standard error of the difference of the two means (seed-to-seed spread)
                    se = math.sqrt(sum(statistics.variance([r[k] for r in runs]) / len(runs)
                                       for runs in (before[alg][m], after[alg][m])
                                       if len(runs) > 1))
                    z = f"{(x - b) / se:+.1f}" if se > 0 else "exact"
                    print(f"| {alg} | {m} | {metric} | {b:.1f} | {x:.1f} | {(x - b) / b:+.0%} "
                          f"| {z} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="mode", required=True)
    for name in ("maps", "grid"):
        p = sub.add_parser(name)
        p.add_argument("--src", default=DEFAULT_SRC, help="patrolling_sim source tree")
        p.add_argument("--algs", nargs="+")
        p.add_argument("--seeds", type=int, default=5)
        p.add_argument("--json")
    sub.choices["maps"].add_argument("--maps", nargs="+",
                                     default=["cumberland", "DIAG_labs", "broughton"])
    sub.choices["maps"].add_argument("--robots", type=int, default=4)
    sub.choices["grid"].add_argument(
        "--ros-json", help="ROS-mode figures {alg: [avg, max, visits]} for the last column")
    sub.choices["maps"].add_argument("--duration", type=float, default=3600.0)
    sub.choices["maps"].add_argument("--interference", action="store_true",
                                     help="model robot-robot interference (default off)")
    d = sub.add_parser("diff", help="changes > threshold between two maps --json files")
    d.add_argument("before")
    d.add_argument("after")
    d.add_argument("--threshold", type=float, default=0.05)
    a = ap.parse_args()
    if a.mode == "diff":
        return run_diff(a)
    if a.seeds < 1:
        ap.error(f"argument --seeds: must be >= 1, got {a.seeds}")
    return run_maps(a) if a.mode == "maps" else run_grid(a)


if __name__ == "__main__":
    sys.exit(main())
