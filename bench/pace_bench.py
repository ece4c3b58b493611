#!/usr/bin/python3
"""Do the figures depend on the pace? The same seeds at several ``--speedup`` values, quiet or
beside a CPU-heavy job, through the runner (docs/pace.md).

For every algorithm x seed x pace one run (``scripts/start_experiments.py``, default: the
abstract world, grid, 4 robots at their default start vertices, 300 sim s after GO,
``--processes shared``); prints per algorithm and seed the average idleness (mean of the
monitor's samples, as the fidelity tables) and the maximum (info.csv) at each pace, the
largest relative difference between the paces of each, the achieved pace and the clock
holds / timed-out waits from the run record (``<prefix>_run.yaml``, ``clock``), and the
interferences (info.csv; on the full stack robots that meet pause, which moves the
figures). Files are read with the report's reader (``patrolling_sim.report.loading.load_run``).

``--load N`` starts N busy-loop processes (in a process group of their own) before the runs
and stops them after. Runs at a pace of at most 2 use little CPU; ``--parallel K`` runs up
to K of them at a time (every other run goes alone). ``--nav`` / ``--loc`` pass through to the
runner (``--nav spqrel_nav_lite --loc AMCL`` for the full stack); ``--extra`` more flags. After each
algorithm's seeds the table has a ``mean`` line: per pace, the mean over its seeds (and
repetitions) of the average and the maximum idleness, and their largest relative difference.
``--table-from JSON`` prints the table of a ``--json`` file written before, running nothing.

Usage:
    bench/pace_bench.py [--algs CGG SEBS DTAG DTAP] [--seeds 1 2 3] [--speedups 1 20 auto]
        [--duration 300] [--repeats 1] [--load N] [--parallel K] [--nav abstract] [--loc LOC]
        [--map grid] [--robots 4] [--keep DIR] [--markdown FILE] [--json FILE]
    bench/pace_bench.py --table-from FILE.json
"""
import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))

#: runs at a pace up to this may run side by side (--parallel): they use little CPU
SLOW_PACE = 2.0


def pace_arg(text):
    """A ``--speedups`` value: a number > 0, or ``auto`` (0, the runner's ``--speedup
    auto``)."""
    if text.strip().lower() == "auto":
        return 0.0
    v = float(text)
    if not v > 0:
        raise ValueError(text)
    return v


def pace_name(pace):
    """``--speedup``'s text for a pace (0: auto)."""
    return "auto" if pace == 0 else f"{pace:g}"


def start_load(n):
    """N busy-loop processes in a new process group; returns the leader's Popen or None."""
    if n <= 0:
        return None
    code = ("import os, sys, subprocess\n"
            f"kids = [subprocess.Popen([sys.executable, '-c', 'while True: pass']) "
            f"for _ in range({n - 1})]\n"
            "while True: pass\n")
    return subprocess.Popen([sys.executable, "-c", code], start_new_session=True)


def stop_load(proc):
    if proc is not None:
        try:
            os.killpg(proc.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        proc.wait()


def run_one(a, alg, seed, pace, out, rep=0):
    """One run; returns its figures (dict) read from the files it wrote under ``out``."""
    from patrolling_sim.report.loading import find_result_sets, load_run
    from patrolling_sim.monitor.run_status import read_run_yaml
    from patrolling_sim.runner.rosenv import workspace_env
    os.makedirs(out, exist_ok=True)
    cmd = ["/usr/bin/python3", START, "--headless", "--map", a.map, "--robots", str(a.robots),
           "--alg", alg, "--nav", a.nav, "--timeout", f"{a.duration:g}", "--speedup",
           pace_name(pace), "--seed", str(seed), "--processes", a.processes, "--results-dir", out]
    if a.loc:
        cmd += ["--loc", a.loc]
    cmd += a.extra
    t0 = time.monotonic()
    with open(os.path.join(out, "runner.log"), "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=workspace_env(),
                                cwd=out, start_new_session=True)
        try:
            code = proc.wait()
        except BaseException:           # Ctrl-C: the runner (own session) stops its run
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait()
            raise
    row = {"alg": alg, "seed": seed, "rep": rep, "pace": pace, "exit": code,
           "wall": round(time.monotonic() - t0, 1)}
    prefixes = find_result_sets([out]).prefixes
    if len(prefixes) != 1:
        return row
    run = load_run(prefixes[0])
    clock = (read_run_yaml(prefixes[0]) or {}).get("clock") or {}
    row.update(prefix=prefixes[0], status=run.status,
               avg=float(run.samples["Idleness"].mean()) if len(run.samples) else None,
               max=run.info["idl_max"], visits=run.info["total_visits"],
               interferences=run.info["interferences"],
               achieved=clock.get("pace_achieved"), holds=clock.get("holds"),
               timeouts=clock.get("hold_timeouts"))
    return row


def spread(values):
    """Largest relative difference between the values (max - min) / min, or None."""
    v = [x for x in values if x is not None]
    if len(v) < 2 or min(v) <= 0:
        return None
    return (max(v) - min(v)) / min(v)


def table(rows, paces):
    """Markdown table: one line per algorithm, seed and repetition."""
    by = {(r["alg"], r["seed"], r["rep"], r["pace"]): r for r in rows}
    keys = sorted({(r["alg"], r["seed"], r["rep"]) for r in rows})
    ps = " / ".join("auto" if p == 0 else f"x{p:g}" for p in paces)
    lines = [f"| alg | seed | avg idleness s ({ps}) | max idleness s ({ps}) | diff avg | "
             f"diff max | achieved pace | holds (timed out) | interferences |", "|---" * 9 + "|"]

    def fmt(x, spec=".1f"):
        return "-" if x is None else format(x, spec)

    for alg, seed, rep in keys:
        rs = [by.get((alg, seed, rep, p), {}) for p in paces]
        avg = [r.get("avg") for r in rs]
        mx = [r.get("max") for r in rs]
        da, dm = spread(avg), spread(mx)
        lines.append(
            f"| {alg} | {seed}{f' ({rep + 1})' if rep else ''} | "
            f"{' / '.join(fmt(x) for x in avg)} | "
            f"{' / '.join(fmt(x) for x in mx)} | {fmt(da, '.1%')} | {fmt(dm, '.1%')} | "
            f"{' / '.join(fmt(r.get('achieved'), '.2f') for r in rs)} | "
            + " / ".join(f"{fmt(r.get('holds'), 'd')} ({fmt(r.get('timeouts'), 'd')})"
                         for r in rs) + " | "
            + " / ".join(fmt(r.get("interferences"), "d") for r in rs) + " |")
        if alg_done(keys, alg, seed, rep):
            avg, mx = seed_means(rows, alg, paces)
            lines.append(
                f"| {alg} | mean | {' / '.join(fmt(x) for x in avg)} | "
                f"{' / '.join(fmt(x) for x in mx)} | {fmt(spread(avg), '.1%')} | "
                f"{fmt(spread(mx), '.1%')} | | | |")
    return "\n".join(lines)


def alg_done(keys, alg, seed, rep):
    """True after the last row of ``alg`` when it has more than one seed or repetition."""
    mine = [k for k in keys if k[0] == alg]
    return len(mine) > 1 and mine[-1] == (alg, seed, rep)


def seed_means(rows, alg, paces):
    """Per pace, the mean over ``alg``'s runs of the average and of the maximum idleness.

    A pace gets None when any of the algorithm's seeds or repetitions has no figure there, so
    a mean is only ever over the same runs at every pace."""
    keys = {(r["seed"], r["rep"]) for r in rows if r["alg"] == alg}
    by = {(r["seed"], r["rep"], r["pace"]): r for r in rows if r["alg"] == alg}
    out = ([], [])
    for p in paces:
        for i, m in enumerate(("avg", "max")):
            v = [by.get((s, k, p), {}).get(m) for s, k in keys]
            out[i].append(None if not v or None in v else sum(v) / len(v))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--algs", nargs="+", default=["CGG", "SEBS", "DTAG", "DTAP"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    ap.add_argument("--speedups", nargs="+", type=pace_arg, default=[1.0, 20.0],
                    help="paces: numbers > 0, or auto (the abstract world only)")
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--repeats", type=int, default=1,
                    help="runs of each algorithm, seed and pace (the spread at one pace)")
    ap.add_argument("--load", type=int, default=0, help="busy-loop processes beside the runs")
    ap.add_argument("--parallel", type=int, default=1,
                    help=f"runs at a pace <= {SLOW_PACE:g} at a time")
    ap.add_argument("--nav", default="abstract")
    ap.add_argument("--loc")
    ap.add_argument("--map", default="grid")
    ap.add_argument("--robots", type=int, default=4)
    ap.add_argument("--processes", default="shared")
    ap.add_argument("--extra", nargs=argparse.REMAINDER, default=[],
                    help="further runner flags (last on the command line)")
    ap.add_argument("--keep", help="keep the runs' files in this folder")
    ap.add_argument("--markdown", help="also write the table to this file")
    ap.add_argument("--json", help="also write every run's figures to this file")
    ap.add_argument("--table-from", metavar="JSON",
                    help="print the table of a --json file written before, and run nothing")
    a = ap.parse_args()
    if a.table_from:
        try:
            with open(a.table_from, encoding="utf-8") as f:
                rows = json.load(f)
            paces = sorted({r["pace"] for r in rows}, key=lambda p: (p == 0, p))  # auto last
            text = table(rows, paces)
        except (OSError, ValueError, KeyError, TypeError) as e:
            sys.exit(f"pace_bench.py: --table-from {a.table_from}: {e}")
        print(text)
        return 0
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))    # stop the runs, then exit
    out = a.keep or tempfile.mkdtemp(prefix="pace_bench_")
    jobs = [(alg, seed, pace, k) for pace in a.speedups for alg in a.algs for seed in a.seeds
            for k in range(a.repeats)]
    load = start_load(a.load)
    rows = []
    try:
        def one(job):
            alg, seed, pace, k = job
            r = run_one(a, alg, seed, pace,
                        os.path.join(out, f"{alg}_s{seed}_x{pace_name(pace)}"
                                     + (f"_r{k}" if k else "")), k)
            print(f"{alg} seed {seed} x{pace_name(pace)} run {k}: exit {r['exit']}, avg "
                  f"{r.get('avg')}, max {r.get('max')}, achieved {r.get('achieved')}, holds "
                  f"{r.get('holds')} ({r.get('timeouts')} timed out), wall {r['wall']} s",
                  flush=True)
            return r
        slow = [j for j in jobs if 0 < j[2] <= SLOW_PACE]
        with ThreadPoolExecutor(max(1, a.parallel)) as pool:
            rows += list(pool.map(one, slow))
        rows += [one(j) for j in jobs if j not in slow]
    finally:
        stop_load(load)
    head = (f"{a.nav}{' ' + a.loc if a.loc else ''}, {a.map}, {a.robots} robots, "
            f"{a.duration:g} s after GO, --processes {a.processes}, "
            f"{'beside ' + str(a.load) + ' busy loop(s)' if a.load else 'quiet'}; "
            f"runs in {out}")
    text = head + "\n\n" + table(rows, a.speedups)
    print("\n" + text)
    if a.markdown:
        with open(a.markdown, "w", encoding="utf-8") as f:
            f.write(text + "\n")
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(rows, f, indent=1)
    return 0 if all(r["exit"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
