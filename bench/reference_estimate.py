#!/usr/bin/python3
"""Estimate of the full reference campaign (campaigns/reference.yaml) from a stratified sample.

    bench/reference_estimate.py [--campaign campaigns/reference.yaml] [--durations 300,600]
                                [--fraction 1.0] [--workers 2] [--seed 0]

Every (map, team size, algorithm) cell of the campaign (or a random ``--fraction`` of them) is
run once, with the campaign's first seed, at each of the short ``--durations``, through the
same worker function the campaign engine runs (simulation, files read back, metrics). Per
cell, CPU s = a + b * duration is fitted on the short runs (a: set-up, b: simulation per
simulated second) and extrapolated to the campaign's duration, times its seed count. Prints
the per-map CPU time, the total, and the wall time on ``--workers`` workers (total / workers
plus the engine's cost per run measured by bench/campaign_bench.py, ``--engine-ms``), and the
slowest cells. ``--from-campaign DIR`` instead extrapolates from the runs a (partial) campaign
folder of the same campaign has done: the mean ``cpu_s`` of each cell's finished runs (full
duration) times the seed count (every cell needs one finished run). CPU s are the thread's
own (``time.thread_time``), so the figure depends less on the machine's load than wall time;
the wall time assumes the workers each get a whole core.
"""
import argparse
import datetime
import os
import platform
import random
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--campaign", default=os.path.join(ROOT, "campaigns", "reference.yaml"))
    ap.add_argument("--durations", default="300,600",
                    help="short durations (s) each sampled cell runs at (two or more)")
    ap.add_argument("--fraction", type=float, default=1.0, help="share of the cells sampled")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--engine-ms", type=float, default=8.0,
                    help="engine cost per run (ms), from bench/campaign_bench.py")
    ap.add_argument("--seed", type=int, default=0, help="sampling seed")
    ap.add_argument("--from-campaign", metavar="DIR",
                    help="extrapolate from the finished runs of this campaign folder instead")
    a = ap.parse_args()
    durs = sorted(float(x) for x in a.durations.split(","))
    if len(durs) < 2 or not 0 < a.fraction <= 1:
        ap.error("give two durations or more and 0 < --fraction <= 1")
    import numpy as np
    from patrolling_sim.campaign.spec import load_campaign
    from patrolling_sim.campaign.tasks import WorldCache, run_graph_task
    worlds = WorldCache()                      # graphs kept across the runs, as a worker's
    camp = load_campaign(a.campaign)
    runs = camp.runs
    seeds = sorted({r.config["seed"] for r in runs})
    full_dur = {r.config["duration"] for r in runs}
    assert len(full_dur) == 1, "one duration per campaign expected"
    full_dur = float(full_dur.pop())
    cells = {}
    for r in runs:
        cells.setdefault((r.config["map"], r.config["robots"], r.config["alg"]), r.config)
    keys = sorted(cells)
    if a.from_campaign:
        import pandas as pd
        table = os.path.join(a.from_campaign, "runs.csv")
        if not os.path.isfile(table):
            sys.exit(f"reference_estimate.py: --from-campaign: no runs.csv in {a.from_campaign} "
                     "(a campaign writes it when it ends or is interrupted)")
        df = pd.read_csv(table)
        df = df[df["status"].isin(["TIMEOUT", "CYCLES"])]
        g = df.groupby(["map", "robots", "alg"])["cpu_s"].mean()
        missing = [k for k in keys if k not in g.index]
        if missing:
            sys.exit(f"reference_estimate.py: {len(missing)} cells without a finished run in "
                     f"{a.from_campaign} (e.g. {missing[0]})")
        report(a, runs, keys, seeds, {k: float(g[k]) for k in keys}, keys,
               f"{len(df)} finished runs of {a.from_campaign} (full duration, mean cpu_s per "
               "cell)")
        return
    sample = keys if a.fraction >= 1 else sorted(
        random.Random(a.seed).sample(keys, max(1, round(a.fraction * len(keys)))))
    print(f"# reference campaign estimate: {len(runs)} runs ({len(keys)} cells x {len(seeds)} "
          f"seeds, {full_dur:.0f} s); sampling {len(sample)} cells at {durs} s", flush=True)
    est, cpu_used, t0 = {}, 0.0, time.perf_counter()
    for i, k in enumerate(sample):
        ys = []
        for d in durs:
            c = dict(cells[k], seed=seeds[0], duration=d)
            res = run_graph_task(c, worlds)
            ys.append(res["cpu_s"])
            cpu_used += res["cpu_s"]
        b, a0 = np.polyfit(durs, ys, 1)
        est[k] = max(a0 + b * full_dur, max(ys))      # never below what was measured
        if (i + 1) % 50 == 0:
            print(f"  {i + 1}/{len(sample)} cells, {cpu_used:.0f} CPU s so far", flush=True)
    report(a, runs, keys, seeds, est, sample,
           f"{cpu_used:.0f} CPU s, {time.perf_counter() - t0:.0f} s wall")


def report(a, runs, keys, seeds, est, sample, how):
    """Print the extrapolation of ``est`` (CPU s per run at full duration, per cell)."""
    import numpy as np
    per_cell = np.mean(list(est.values()))
    total = per_cell * len(keys) * len(seeds)        # a sample stands for its share of cells
    by_map, by_alg = {}, {}
    for (m, n, alg), v in est.items():
        by_map[m] = by_map.get(m, 0.0) + v * len(seeds) * len(keys) / len(sample)
        by_alg[alg] = by_alg.get(alg, 0.0) + v * len(seeds) * len(keys) / len(sample)
    engine = len(runs) * a.engine_ms / 1000.0
    wall = total / a.workers + engine / a.workers
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    print(f"\nhost {platform.node()}, {stamp} UTC, load avg {os.getloadavg()[0]:.2f}; "
          f"sample: {how}\n")
    print("| map | CPU s (full campaign, estimated) |\n|---|---|")
    for m, v in sorted(by_map.items(), key=lambda kv: -kv[1]):
        print(f"| {m} | {v:.0f} |")
    print(f"| **total** | **{total:.0f}** ({total / 3600:.2f} CPU h) |\n")
    print("| algorithm | CPU s (full campaign, estimated) |\n|---|---|")
    for m, v in sorted(by_alg.items(), key=lambda kv: -kv[1]):
        print(f"| {m} | {v:.0f} |")
    print()
    print(f"wall on {a.workers} worker(s): {wall / 60:.1f} min (CPU / workers, plus "
          f"{a.engine_ms:g} ms engine cost per run); 1 worker: "
          f"{(total + engine) / 60:.1f} min\n")
    print("slowest cells (CPU s per run at full duration):")
    for k, v in sorted(est.items(), key=lambda kv: -kv[1])[:10]:
        print(f"  {k[0]}_{k[1]} {k[2]}: {v:.2f}")
    print("\ncommand: bench/reference_estimate.py " + " ".join(sys.argv[1:]))
    print(f"full run: scripts/campaign.py {os.path.relpath(a.campaign, ROOT)} --workers "
          f"{a.workers}")


if __name__ == "__main__":
    main()
