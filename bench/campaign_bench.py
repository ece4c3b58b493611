#!/usr/bin/python3
"""Campaign engine benchmark: graph-mode runs per second through scripts/campaign.py
with 1 and with 2 Dask workers, and the engine's overhead per run compared with calling the
same worker function in a loop in one process.

    bench/campaign_bench.py [--runs 1000] [--map grid] [--robots 4] [--alg CR] [--duration 600]
                            [--repeat 3]

Each measurement is a fresh campaign folder (nothing skipped). Prints a Markdown table. The
loop baseline runs the same function the workers run (simulation, files read back, metrics);
the client's storing of files and records is part of the campaign figures. A second loop also
stores each run's files and state record as the client does (the same work as a campaign
without its engine); the overhead is also given against it, in wall and in CPU time (a 1-worker
campaign stores on the other core while its worker runs). The engine's
throughput is measured without its start: each campaign records in its provenance.yaml the
time from the runs' submission to the last run stored (the "runs phase"); runs per second,
the speed-up and the overhead per run are given on it, and for the whole command (interpreter
start, campaign validation, LocalCluster start and stop, runs.csv). A 1-run campaign shows
the start's cost. CPU seconds are the campaign process tree's (client, scheduler, workers,
and the workers' forkserver, which ends just after the command: this process is their
subreaper).

Each measurement is repeated ``--repeat`` times and the fastest is kept (as ``timeit`` does:
on a shared virtual machine the slower repetitions measure the neighbours, not the code); the
range and the median of the repetitions are printed beside it. The repetitions are
interleaved (loop, 1 worker, 2 workers, 1 run; then again), so that a slow spell of the
machine touches every measurement alike instead of all repetitions of one.
"""
import argparse
import datetime
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
#: the workspace's two Python packages' source folders (the programs need both, unsourced)
SRC = os.pathsep.join(os.path.join(ROOT, "src", p, "src")
                      for p in ("patrolling_sim", "spqrel_nav_lite"))
sys.path[:0] = SRC.split(os.pathsep)


def campaign_file(d, a, runs=None, name="bench.yaml"):
    import yaml
    path = os.path.join(d, name)
    with open(path, "w") as f:
        yaml.safe_dump({"name": "bench", "mode": "graph",
                        "fixed": {"map": a.map, "robots": a.robots, "alg": a.alg,
                                  "duration": a.duration},
                        "seeds": runs or a.runs}, f)
    return path


def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _become_subreaper():
    """Linux: processes orphaned below this one (the campaign's workers' forkserver, which
    exits just after the campaign command) become its children, so that their CPU time is
    counted with the command's when they are reaped (:func:`_reap_orphans`)."""
    import ctypes
    libc = ctypes.CDLL(None, use_errno=True)
    PR_SET_CHILD_SUBREAPER = 36
    if libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) != 0:
        sys.exit("campaign_bench: prctl(PR_SET_CHILD_SUBREAPER) failed: "
                 f"{os.strerror(ctypes.get_errno())}")


def _reap_orphans():
    """Wait for every child left (orphans handed to this subreaper)."""
    while True:
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            return


def timed_campaign(path, out, workers, runs):
    """(wall s, CPU s, runs s) of one campaign command: wall until the command returns; CPU
    of the command's whole process tree, including processes that end just after it; the
    time from the runs' submission to the last run stored, as the campaign records it in
    its provenance.yaml (``timing``: the engine's throughput without its start). ``runs``:
    the campaign's run count; the benchmark stops if it stored fewer."""
    env = dict(os.environ, PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""), PYTHONPATH=SRC)
    c0 = _children_cpu()
    t0 = time.perf_counter()
    p = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "campaign.py"), path,
                        "--out", out, "--workers", str(workers), "--no-report"],
                       capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if p.returncode:
        sys.exit(f"campaign_bench: campaign failed: {p.stderr[-500:]}")
    _reap_orphans()
    cpu = _children_cpu() - c0
    import yaml
    with open(os.path.join(out, "provenance.yaml")) as f:
        timing = yaml.safe_load(f)["timing"]
    if timing["runs_stored"] != runs:
        sys.exit(f"campaign_bench: the campaign stored {timing['runs_stored']} runs, not {runs}")
    return wall, cpu, timing["runs_s"]


def timed_loop(path, store_out=None):
    """(wall s, CPU s) of the campaign's runs made one after the other in this process by the
    workers' function; with ``store_out``, each run's files and state record are also stored
    there as the campaign's client stores them (``campaign_store.store_result``), so that the
    loop does all the work of the campaign and only the engine (Dask, processes, transfers,
    the overlap of storing and running) differs."""
    from patrolling_sim.campaign.spec import load_campaign
    from patrolling_sim.campaign.tasks import run_graph_task
    from patrolling_sim.campaign.store import store_result
    from patrolling_sim.campaign.tasks import WorldCache
    camp = load_campaign(path)
    worlds = WorldCache()                      # kept across the runs, as a worker's
    run_graph_task(camp.runs[0].config, worlds)    # imports and caches warm, as in a worker
    next_free = {}
    c0 = time.process_time()
    t0 = time.perf_counter()
    for r in camp.runs:
        res = run_graph_task(r.config, worlds)
        if store_out is not None:
            store_result(store_out, r, res, camp, next_free)
    return time.perf_counter() - t0, time.process_time() - c0


def file_creation_ms(d, n=300):
    """(wall ms, kernel CPU ms) of creating one 4-kB file with the client's own writer
    (``campaign_store.write_atomic``: create ``.part``, write, close, rename), over ``n`` new
    files in a new folder under ``d``. The files stay until the benchmark's folder is
    removed: removing them here would slow down the very creations measured next (see the
    printed note)."""
    from patrolling_sim.campaign.store import write_atomic
    sub = os.path.join(d, "file_creation")
    os.makedirs(sub)
    text = "x" * 4096
    s0 = resource.getrusage(resource.RUSAGE_SELF).ru_stime
    t0 = time.perf_counter()
    for i in range(n):
        write_atomic(os.path.join(sub, f"f{i}.csv"), text)
    wall = time.perf_counter() - t0
    return 1000 * wall / n, 1000 * (resource.getrusage(resource.RUSAGE_SELF).ru_stime - s0) / n


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--map", default="grid")
    ap.add_argument("--robots", type=int, default=4)
    ap.add_argument("--alg", default="CR")
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--repeat", type=int, default=3, help="repetitions per measurement "
                    "(the fastest is kept)")
    a = ap.parse_args()
    if a.runs < 1 or a.repeat < 1:
        ap.error("--runs and --repeat must be >= 1")
    _become_subreaper()
    tmp = tempfile.mkdtemp(prefix="campaign_bench_")
    names = ("loop in one process", "campaign, 1 worker", "campaign, 2 workers",
             "campaign of 1 run (fixed cost)", "loop in one process, storing the files")
    got = {name: [] for name in names}
    try:
        creation = file_creation_ms(tmp)
        path = campaign_file(tmp, a)
        one_path = campaign_file(tmp, a, 1, "one.yaml")
        for i in range(a.repeat):          # interleaved: see the module's docstring
            got[names[0]].append(timed_loop(path))
            got[names[1]].append(timed_campaign(path, os.path.join(tmp, f"w1_{i}"), 1, a.runs))
            got[names[2]].append(timed_campaign(path, os.path.join(tmp, f"w2_{i}"), 2, a.runs))
            got[names[3]].append(timed_campaign(one_path, os.path.join(tmp, f"one_{i}"), 1, 1))
            got[names[4]].append(timed_loop(path, os.path.join(tmp, f"loop_{i}")))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    spread = {k: (min(t[0] for t in v), statistics.median(t[0] for t in v),
                  max(t[0] for t in v)) for k, v in got.items()}
    loop, w1, w2, one, stored = (min(got[k]) for k in names)
    # the engine's throughput: from the runs' submission to the last run stored (the
    # campaign's own record), fastest of the repetitions
    r1, r2 = (min(t[2] for t in got[k]) for k in names[1:3])
    n = a.runs
    fixed_cpu = one[1] - stored[1] / n
    uptime = os.getloadavg()
    print(f"Machine: {platform.node()}, {os.cpu_count()} cores, load avg at the end "
          f"{uptime[0]:.2f}, "
          f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; "
          f"{n} runs of {a.map}/{a.robots} robots/{a.alg}/{a.duration:.0f} s, "
          f"fastest of {a.repeat}")
    print(f"File creation at the start: {creation[0]:.3f} ms per file ({creation[1]:.3f} ms of "
          "kernel CPU). A campaign's client creates 9 files per graph run; on an ext4 file system "
          "without a journal each creation costs about 10x more (0.4-0.6 ms instead of 0.04 on "
          "the VM of bench/notes/campaign.md) for minutes after many files were deleted, "
          "which lowers the 2-worker figures.\n")
    print(f"| how | wall (s) | runs/s | per run (ms) | CPU (s) | wall range of {a.repeat} (s) | "
          "median (s) | runs phase (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, res in zip(names, (loop, w1, w2, one, stored)):
        t, c = res[:2]
        k = 1 if name.endswith("(fixed cost)") else n
        lo, med, hi = spread[name]
        phase = {names[1]: f"{r1:.2f}", names[2]: f"{r2:.2f}"}.get(name, "")
        print(f"| {name} | {t:.1f} | {k / t:.2f} | {1000 * t / k:.1f} | {c:.1f} | "
              f"{lo:.1f}-{hi:.1f} | {med:.1f} | {phase} |")
    print(f"\nthe engine once the runs are submitted (runs phase: from their submission to the "
          f"last run stored, as the campaign records it): 1 worker {n / r1:.1f} runs/s, 2 "
          f"workers {n / r2:.1f} runs/s, speed-up **{r1 / r2:.2f}x**; overhead per run with 1 "
          f"worker against the loop **{100 * (r1 - loop[0]) / loop[0]:+.1f} %** "
          f"({1000 * (r1 - loop[0]) / n:+.2f} ms per run)")
    print(f"the whole command (interpreter, validation, the cluster's start and stop, runs.csv; "
          f"a 1-run campaign takes {one[0]:.2f} s): speed-up 2 vs 1 worker {w1[0] / w2[0]:.2f}x; "
          f"overhead with 1 worker {100 * (w1[0] - loop[0]) / loop[0]:+.1f} %")
    print(f"against the loop that also stores the files (the same work without the engine): "
          f"1 worker {100 * (w1[0] - stored[0]) / stored[0]:+.1f} % wall, runs phase "
          f"{100 * (r1 - stored[0]) / stored[0]:+.1f} % (the client stores while the worker "
          f"runs); CPU of the whole campaign {100 * (w1[1] - stored[1]) / stored[1]:+.1f} % with "
          f"1 worker, {100 * (w2[1] - stored[1]) / stored[1]:+.1f} % with 2 (without a 1-run "
          f"campaign's {fixed_cpu:.1f} CPU s: "
          f"{100 * (w1[1] - fixed_cpu - stored[1]) / stored[1]:+.1f} "
          f"and {100 * (w2[1] - fixed_cpu - stored[1]) / stored[1]:+.1f} %)")
    # the same figures per repetition (each from measurements taken one after the other)
    over = [(100 * (w[0] - lt[0]) / lt[0], 100 * (w[2] - lt[0]) / lt[0], w[2] / v[2])
            for lt, w, v in zip(got[names[0]], got[names[1]], got[names[2]])]
    print("per repetition: overhead with 1 worker, whole command (runs phase): " +
          ", ".join(f"{x:+.1f} % ({y:+.1f} %)" for x, y, _ in over) +
          f"; median {statistics.median(x for x, _, _ in over):+.1f} % "
          f"({statistics.median(y for _, y, _ in over):+.1f} %); runs-phase speed-up " +
          ", ".join(f"{z:.2f}x" for _, _, z in over))


if __name__ == "__main__":
    main()
