#!/usr/bin/python3
"""Benchmark scripts/report.py on a synthetic results set of a given size.

    bench/report_bench.py [--runs-per-alg R] [--samples S] [--algs K]

Writes R runs per algorithm (K algorithms) on grid N=4 and on cumberland N=4, each with
S idleness samples in the original format, then times one report.py run (wall clock).
"""
import argparse
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
ALGS = ("CR", "HCR", "HPCC", "RAND", "SEBS", "GBS", "CBLS", "DTAG", "DTAP", "CGG", "MSP")
MAPS = (("grid", 25), ("cumberland", 40))


def write(root, rng, map_name, v, alg, k, samples, level):
    folder = os.path.join(root, f"{map_name}_4", alg, "bench")
    os.makedirs(folder, exist_ok=True)
    prefix = os.path.join(folder, f"20260101_{k:06d}")
    t, vals = 30.0, []
    with open(prefix + "_idleness.csv", "w") as f:
        f.write("Time;Robot;Node;Idleness;Interferences\n")
        for _ in range(samples):
            t += rng.uniform(0.1, 2.0)
            x = round(rng.expovariate(1.0 / level), 1)
            vals.append(x)
            f.write("%.1f;%d;%d;%.1f;0\n" % (t, rng.randrange(4), rng.randrange(v), x))
    avg = sum(vals) / len(vals)
    with open(prefix + "_info.csv", "w") as f:
        f.write(f"{map_name};4;default;0.0;0.00;graph;{alg};;bench;20260101_{k:06d};{t:.1f};"
                f"1.0;0;TIMEOUT;{min(vals):.1f};{avg:.1f};0.0;{max(vals):.1f};0.00;"
                f"{samples};{samples / v:.1f};5\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs-per-alg", type=int, default=5)
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--algs", type=int, default=4)
    ap.add_argument("--no-run-plots", action="store_true")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="report_bench_")
    try:
        rng = random.Random(1)
        k = 0
        for map_name, v in MAPS:
            for i, alg in enumerate(ALGS[:a.algs]):
                for _ in range(a.runs_per_alg):
                    k += 1
                    write(os.path.join(tmp, "res"), rng, map_name, v, alg, k, a.samples,
                          30.0 + 5 * i)
        t0 = time.monotonic()
        subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "report.py"),
                        os.path.join(tmp, "res"), "--out", os.path.join(tmp, "out"), "-q"]
                       + (["--no-run-plots"] if a.no_run_plots else []),
                       check=True)
        wall = time.monotonic() - t0
        size = os.path.getsize(os.path.join(tmp, "out", "report.html")) / 1e6
        print(f"{k} runs x {a.samples} samples ({k * a.samples} samples, {len(MAPS)} maps, "
              f"{a.algs} algorithms): report.py {wall:.1f} s wall, report.html {size:.1f} MB")
    finally:
        shutil.rmtree(tmp)


if __name__ == "__main__":
    main()
