#!/usr/bin/python3
"""Campaign engine benchmark (issue 14): graph-mode runs per second through scripts/campaign.py
with 1 and with 2 Dask workers, and the engine's overhead per run compared with calling the
same worker function in a loop in one process.

    bench/campaign_bench.py [--runs 1000] [--map grid] [--robots 4] [--alg CR] [--duration 600]

Each measurement is a fresh campaign folder (nothing skipped). Prints a Markdown table. The
loop baseline runs the same function the workers run (simulation + reading the files back);
the client's storing of files and metrics is part of the campaign figures.
"""
import argparse
import datetime
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
SRC = os.path.join(ROOT, "src", "patrolling_sim", "src")
sys.path.insert(0, SRC)


def campaign_file(d, a):
    import yaml
    path = os.path.join(d, "bench.yaml")
    with open(path, "w") as f:
        yaml.safe_dump({"name": "bench", "mode": "graph",
                        "fixed": {"map": a.map, "robots": a.robots, "alg": a.alg,
                                  "duration": a.duration},
                        "seeds": a.runs}, f)
    return path


def timed_campaign(path, out, workers):
    env = dict(os.environ, PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""), PYTHONPATH=SRC)
    t0 = time.perf_counter()
    p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "campaign.py"), path,
                        "--out", out, "--workers", str(workers), "--no-report"],
                       capture_output=True, text=True, env=env)
    if p.returncode:
        sys.exit(f"campaign_bench: campaign failed: {p.stderr[-500:]}")
    return time.perf_counter() - t0


def timed_loop(path):
    from patrolling_sim.campaign import load_campaign, run_graph_task
    camp = load_campaign(path)
    t0 = time.perf_counter()
    for r in camp.runs:
        run_graph_task(r.config)
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--map", default="grid")
    ap.add_argument("--robots", type=int, default=4)
    ap.add_argument("--alg", default="CR")
    ap.add_argument("--duration", type=float, default=600.0)
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="campaign_bench_")
    try:
        path = campaign_file(tmp, a)
        loop = timed_loop(path)
        w1 = timed_campaign(path, os.path.join(tmp, "w1"), 1)
        w2 = timed_campaign(path, os.path.join(tmp, "w2"), 2)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    n = a.runs
    print(f"Machine: {platform.node()}, {os.cpu_count()} cores, "
          f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; "
          f"{n} runs of {a.map}/{a.robots} robots/{a.alg}/{a.duration:.0f} s\n")
    print("| how | wall (s) | runs/s | per run (ms) |")
    print("|---|---|---|---|")
    for name, t in (("loop in one process", loop), ("campaign, 1 worker", w1),
                    ("campaign, 2 workers", w2)):
        print(f"| {name} | {t:.1f} | {n / t:.2f} | {1000 * t / n:.1f} |")
    print(f"\nspeed-up 2 vs 1 worker: {w1 / w2:.2f}x; engine overhead with 1 worker: "
          f"{100 * (w1 - loop) / loop:+.1f} % per run")


if __name__ == "__main__":
    main()
