#!/usr/bin/python3
"""Scenario measurements in graph mode (docs/scenarios.md): how each algorithm degrades
when robots fail, and what share of messages each communication model delivers.

Part 1 (failures): ``--map`` with ``--robots`` robots, ``--duration`` s, failures
``--attrition``, seeds 0..``--seeds``-1, every algorithm of ``--algs``; per algorithm the
mean over seeds of the graph idleness before the first failure (600 s window), settled after
it (last 600 s), the share of seeds with after > before, the seeds whose trailing 300 s
average settled within 10 % (and the mean settle time), and the paired idleness of the
same seeds without failure over the same last window.

Part 2 (communication): the delivered share of positions and algorithm messages for each
model of ``--comms`` on ``--comm-map`` (SEBS, ``--robots`` robots, 900 s, seed 0).

Part 3 (``--campaign DIR``, instead of 1 and 2): the table of a finished campaign (e.g.
``campaigns/attrition.yaml``): per algorithm, mean over its runs of before / after / settle
time of every failure time (``scenario.scenario_metrics``).

Prints Markdown tables; times in sim seconds; the CPU seconds of the whole bench are given.

Usage:
    bench/scenarios_bench.py [--map cumberland] [--robots 6] [--attrition 2@1200,4@1200]
                             [--seeds 5] [--algs SEBS CBLS ...] [--comm-map cumberland]
"""
import argparse
import os
import resource
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))
from patrolling_sim.algorithms import REGISTRY  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
from patrolling_sim.monitor.metrics import (failure_impact, graph_idleness_series,  # noqa: E402
                                            read_visits)
from patrolling_sim.scenarios.scenario import read_scenario, scenario_columns  # noqa: E402

COMMS = ["perfect", "bernoulli:p=0.3", "ge:p_good=0,p_bad=1,to_bad=0.05,to_good=0.5",
         "range:r=10,los=false", "range:r=10,los=true", "range:r=20,los=true"]


def one(out, **kw):
    sim = GraphSimulator(GraphSimConfig(results_dir=out, **kw))
    sim.run()
    return sim


def failures(a, out):
    print(f"### {a.map}, {a.robots} robots, {a.duration:g} s, failures {a.attrition}, "
          f"seeds 0..{a.seeds - 1}\n")
    print("| algorithm | before (s) | after (s) | after>before | settled | settle time (s) "
          "| after, no failure (s) | vertices unvisited after |")
    print("|---|---|---|---|---|---|---|---|")
    t_end = a.duration
    for alg in a.algs:
        rows = []
        for seed in range(a.seeds):
            sim = one(out, map=a.map, robots=a.robots, alg=alg, duration=a.duration,
                      seed=seed, attrition=a.attrition)
            c = scenario_columns(sim.prefix)
            t1 = c["first_failure"]
            unvisited = sim.g.n - len({x for t, _, x in read_visits(sim.prefix + "_visits.csv")
                                       if t > t1})
            base = one(out, map=a.map, robots=a.robots, alg=alg, duration=a.duration,
                       seed=seed)
            t, s = graph_idleness_series(read_visits(base.prefix + "_visits.csv"), base.g.n,
                                         t_end)
            rows.append((c["idl_before"], c["idl_after"], c["settle_time"],
                         failure_impact(t, s, t1, t_end).after, unvisited))
        n = len(rows)
        mean = lambda k: sum(r[k] for r in rows) / n
        settled = [r[2] for r in rows if r[2] is not None]
        print(f"| {alg} | {mean(0):.1f} | {mean(1):.1f} | "
              f"{sum(r[1] > r[0] for r in rows)}/{n} | {len(settled)}/{n} | "
              f"{(sum(settled) / len(settled)) if settled else float('nan'):.0f} | "
              f"{mean(3):.1f} | {max(r[4] for r in rows)} |")
    print()


def comms(a, out):
    print(f"### Delivered share, {a.comm_map}, SEBS, {a.robots} robots, 900 s, seed 0\n")
    print("| model | positions delivered | algorithm messages delivered | avg idleness (s) |")
    print("|---|---|---|---|")
    for spec in a.comms:
        sim = one(out, map=a.comm_map, robots=a.robots, alg="SEBS", duration=900, seed=0,
                  comm=spec)
        st = sim.monitor.stats(sim.t)
        if spec == "perfect":
            print(f"| {spec} | 1.000 | 1.000 | {st.global_avg:.1f} |")
            continue
        c = read_scenario(sim.prefix)["counters"]["total"]
        print(f"| `{spec}` | {c['positions_delivered'] / c['positions_sent']:.3f} | "
              f"{c['results_delivered'] / c['results_sent']:.3f} | {st.global_avg:.1f} |")
    print()


def campaign_table(root):
    import glob
    from patrolling_sim.model import map_bundle
    from patrolling_sim.monitor.results import parse_info_line
    from patrolling_sim.scenarios.scenario import scenario_metrics
    per = {}
    for yml in sorted(glob.glob(os.path.join(root, "**", "*_scenario.yaml"), recursive=True)):
        prefix = yml[:-len("_scenario.yaml")]
        with open(prefix + "_info.csv") as f:
            info = parse_info_line(f.read().strip().splitlines()[-1])
        m = scenario_metrics(prefix, map_bundle.vertex_count(info["map"]), info["sim_duration"])
        per.setdefault(info["algorithm"], []).append(m)
    if not per:
        sys.exit(f"{root}: no run with a scenario file")
    first = next(iter(per.values()))[0]
    times = [f["t_fail"] for f in first["failures"]]
    print(f"### Campaign {root}: failures {first['schedule']}, mean over runs (s)\n")
    print("| algorithm | runs | " + " | ".join(
        f"{t:g} s: before | after | settled | settle time" for t in times) + " |")
    print("|---|---|" + "---|---|---|---|" * len(times))
    for alg in sorted(per):
        ms = per[alg]
        cells = []
        for k in range(len(times)):
            fs = [m["failures"][k] for m in ms if len(m["failures"]) > k]
            st = [f["settle_time"] for f in fs if f["settle_time"] is not None]
            cells += [f"{sum(f['before'] for f in fs) / len(fs):.1f}",
                      f"{sum(f['after'] for f in fs) / len(fs):.1f}", f"{len(st)}/{len(fs)}",
                      f"{sum(st) / len(st):.0f}" if st else "-"]
        print(f"| {alg} | {len(ms)} | " + " | ".join(cells) + " |")
    print()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--map", default="cumberland")
    ap.add_argument("--robots", type=int, default=6)
    ap.add_argument("--duration", type=float, default=3600.0)
    ap.add_argument("--attrition", default="2@1200,4@1200")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--algs", nargs="+", default=sorted(REGISTRY))
    ap.add_argument("--comm-map", default="cumberland")
    ap.add_argument("--comms", nargs="+", default=COMMS)
    ap.add_argument("--skip-failures", action="store_true")
    ap.add_argument("--campaign", help="a finished campaign folder: its table only")
    a = ap.parse_args()
    if a.campaign:
        campaign_table(a.campaign)
        return
    with tempfile.TemporaryDirectory() as out:
        if not a.skip_failures:
            failures(a, out)
        comms(a, out)
    ru = resource.getrusage(resource.RUSAGE_SELF)
    print(f"CPU: {ru.ru_utime + ru.ru_stime:.1f} s")


if __name__ == "__main__":
    main()
