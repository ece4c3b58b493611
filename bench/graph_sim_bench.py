#!/usr/bin/python3
"""Graph-mode benchmark: wall time and peak memory to simulate one hour of patrolling.

For each map, team size and algorithm, one run of ``--duration`` simulated seconds in a fresh
subprocess (so peak RSS is that run's own), no result files written. Prints a Markdown table
(and writes it to ``--out``).

Usage:
    bench/graph_sim_bench.py [--maps grid cumberland broughton] [--robots 1 4 12]
                             [--algs ...] [--duration 3600] [--interference on|off]
                             [--out bench/notes/graph_sim.md]
"""
import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
ALGS = ["RAND", "CR", "HCR", "HPCC", "CGG", "MSP", "GBS", "SEBS", "CBLS", "DTAG", "DTAP"]

CHILD = r"""
import json, resource, sys, time
sys.path[:0] = [%r, %r]
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
cfg = GraphSimConfig(map=%r, robots=%d, alg=%r, duration=%f, seed=1, **%r)
t0 = time.perf_counter()
sim = GraphSimulator(cfg)
t1 = time.perf_counter()
c1 = time.process_time()
s = sim.run(write=False)
t2 = time.perf_counter()
cpu = time.process_time() - c1
print(json.dumps(dict(setup=t1 - t0, run=t2 - t1, cpu=cpu, rss=resource.getrusage(
    resource.RUSAGE_SELF).ru_maxrss / 1024, visits=s.total_visits, avg=s.global_avg,
    mx=s.global_max)))
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=["grid", "cumberland", "broughton"])
    ap.add_argument("--robots", nargs="+", type=int, default=[1, 4, 12])
    ap.add_argument("--algs", nargs="+", default=ALGS)
    ap.add_argument("--duration", type=float, default=3600.0)
    ap.add_argument("--out", default=None)
    ap.add_argument("--interference", choices=("on", "off"), default=None,
                    help="graph mode's interference model (default: GraphSimConfig's, on)")
    a = ap.parse_args()
    src = os.path.join(ROOT, "src", "patrolling_sim", "src")
    nav_src = os.path.join(ROOT, "src", "spqrel_nav_lite", "src")
    lines = [f"Graph mode, {a.duration:.0f} s simulated per run, seed 1, no files written. "
             f"Machine: {platform.node()}, {os.cpu_count()} cores, "
             f"{platform.processor() or platform.machine()}; {datetime.date.today()}.",
             "Command: `bench/graph_sim_bench.py " + " ".join(sys.argv[1:]) + "`", "",
             "setup = graph, map and start positions (incl. importing OpenCV for the map); run = "
             "the simulation (wall, and the CPU time it used: the figure to compare on a loaded "
             "machine); process = the whole child process (interpreter start, imports, "
             "setup, run), i.e. what one `scripts/graph_sim.py` call costs.", "",
             "| map | N | alg | setup (s) | run (s) | run CPU (s) | process (s) | "
             "speed (x real time) | peak RSS (MB) | visits | avg idl (s) | max idl (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    print("\n".join(lines), flush=True)
    extra = {} if a.interference is None else {"interference": a.interference == "on"}
    for m in a.maps:
        for n in a.robots:
            for alg in a.algs:
                t0 = time.perf_counter()
                out = subprocess.run([sys.executable, "-c",
                                      CHILD % (src, nav_src, m, n, alg, a.duration, extra)],
                                     capture_output=True, text=True, timeout=900)
                proc_wall = time.perf_counter() - t0
                if out.returncode != 0:
                    row = f"| {m} | {n} | {alg} | failed: {out.stderr.strip().splitlines()[-1]} |"
                else:
                    r = json.loads(out.stdout)
                    row = (f"| {m} | {n} | {alg} | {r['setup']:.2f} | {r['run']:.2f} | "
                           f"{r['cpu']:.2f} | {proc_wall:.2f} | "
                           f"{a.duration / max(r['run'], 1e-6):,.0f} | {r['rss']:.0f} | "
                           f"{r['visits']} | {r['avg']:.1f} | {r['mx']:.1f} |")
                lines.append(row)
                print(row, flush=True)
    if a.out:
        with open(a.out, "w", encoding="utf-8") as f:
            f.write("# Graph-mode simulator benchmark\n\n" + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
