#!/usr/bin/python3
"""Fill the fidelity matrix with runs of the ORIGINAL's agents, cell by cell, resumably.

A cell is (map, team size, algorithm). For every cell of the grid given (``--maps``,
``--robots``, ``--algs``, in that order of priority: the first team size varies slowest), the
queue counts the complete runs of the original's agents that the summary CSV already holds
(``--summary``, by default tests/unit/data/original_matrix/runs.csv) and makes more with
bench/original_agents.py, one run per call, up to ``--parallel`` runs side by side (of
different cells), in priority order: a cell gets ``--min-runs`` runs, then one more while the
tolerance of a metric (docs/fidelity_matrix.md: average 10 %, maximum 25 %, visits 10 % of
the mean) is less than three standard errors of the mean of its runs, up to ``--max-runs``
runs, before the queue moves on to later cells.

Each run writes its row to a CSV of its own under ``--work``; a complete run's row (the
monitor's timeout after the whole duration) is appended to the summary under a file lock, so
a queue stopped and started again goes on where it was, and several queues on disjoint cells
(e.g. one per team size) can share the summary. A run in which an agent's process ended
early (the original's CBLS agent can crash) is stored but does not count: the cell gets
another run. A cell whose runs keep failing is given up after ``--max-runs`` + 2 tries. The
original's MSP agent needs its route files, which the original ships (and which fit today's
graphs) for grid only, so MSP cells are planned on grid only.

Usage:
    bench/original_matrix_queue.py --orig-ws PATH [--maps ...] [--robots 4 8 2 12]
        [--algs ...] [--min-runs 2] [--max-runs 5] [--parallel 2] [--duration 1800]
        [--speedup 30] [--work DIR] [--summary CSV] [--dry-run]
"""
import argparse
import csv
import fcntl
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "unit"))
import original_matrix as om  # noqa: E402

MAPS = ("cumberland", "DIAG_floor1", "broughton", "example", "DIAG_labs", "ctcv", "1r5",
        "move_base_arena", "grid")
ALGS = ("CR", "HCR", "HPCC", "CGG", "SEBS", "GBS", "CBLS", "DTAG", "RAND", "DTAP", "MSP")
#: team sizes a map has room for: 12 robots only on maps of at least 24 vertices
MIN_VERTICES_PER_ROBOT = 2


def vertex_count(map_name):
    from patrolling_sim.common import paths
    with open(paths.map_files(map_name)[1], encoding="utf-8") as f:
        return int(f.readline().split()[0])


def existing(summary, duration):
    """{(map, robots, alg): [(avg, max, visits)], ...} and the highest run index per cell."""
    runs, last = {}, {}
    if not os.path.isfile(summary) or os.path.getsize(summary) == 0:
        return runs, last
    for r in om.read_rows(summary):
        if r["agents"] != "original" or r["duration"] != duration:
            continue
        key = (r["map"], r["robots"], r["algorithm"])
        last[key] = max(last.get(key, -1), r["run"])
        if om.complete(r) and not om.crashed(r):      # a crashed agent's run: make another
            runs.setdefault(key, []).append((r["avg_idleness"], r["max_idleness"], r["visits"]))
    return runs, last


def needs_more(runs, max_runs):
    """True while the cell has fewer than ``max_runs`` runs and some metric's tolerance is
    less than three standard errors of its mean."""
    if len(runs) >= max_runs:
        return False
    if len(runs) < 2:
        return True
    for k, m in enumerate(om.METRICS):
        v = [r[k] for r in runs]
        mean = statistics.mean(v)
        se = statistics.stdev(v) / math.sqrt(len(v))
        if mean and 3 * se > om.TOL[m] * abs(mean):
            return True
    return False


def append_locked(summary, path):
    """Append the rows of the CSV ``path`` that are complete runs (the monitor's timeout
    after the whole duration: the summary holds only such runs; a run stopped before, e.g.
    because some agents never started, stays in its own CSV) to ``summary`` under an
    exclusive lock."""
    with open(path, newline="", encoding="utf-8") as f:
        raw = list(csv.DictReader(f))
    rows = [r for r, parsed in zip(raw, om.read_rows(path)) if om.complete(parsed)]
    if not rows:
        return 0
    with open(summary + ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        om.append_rows(summary, rows)
    return len(rows)


def one_run(a, cell, index):
    """Run bench/original_agents.py for one run of ``cell``; returns (cell, rows appended)."""
    map_name, robots, alg = cell
    tag = f"{map_name}_{robots}_{alg}_{index:02d}"
    out = os.path.join(a.work, tag)
    rows = os.path.join(a.work, tag + ".csv")
    # a folder left by a run that was stopped would hold a second set of result files
    shutil.rmtree(out, ignore_errors=True)
    if os.path.exists(rows):
        os.remove(rows)
    cmd = ["nice", "-n", str(a.nice), "/usr/bin/python3",
           os.path.join(ROOT, "bench", "original_agents.py"), "--orig-ws", a.orig_ws,
           "--alg", alg, "--map", map_name, "--robots", str(robots),
           "--duration", f"{a.duration:g}", "--runs", "1", "--first", str(index),
           "--speedup", f"{a.speedup:g}", "--out", out, "--summary", rows]
    t0 = time.monotonic()
    with open(os.path.join(a.work, tag + ".log"), "w", encoding="utf-8") as log:
        rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT)
    n = append_locked(a.summary, rows) if os.path.isfile(rows) else 0
    print(f"{time.strftime('%H:%M:%S')} {tag}: exit {rc}, {n} row(s), "
          f"{time.monotonic() - t0:.0f} wall s", flush=True)
    return cell, n


def plan(a):
    cells = []
    for robots in a.robots:
        for map_name in a.maps:
            if robots * MIN_VERTICES_PER_ROBOT > vertex_count(map_name):
                continue
            for alg in a.algs:
                if alg == "MSP" and map_name != "grid":
                    continue
                cells.append((map_name, robots, alg))
    return cells


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orig-ws", required=True)
    ap.add_argument("--maps", nargs="+", default=list(MAPS))
    ap.add_argument("--robots", nargs="+", type=int, default=[4, 8, 2, 12])
    ap.add_argument("--algs", nargs="+", default=list(ALGS))
    ap.add_argument("--min-runs", type=int, default=2)
    ap.add_argument("--max-runs", type=int, default=5)
    ap.add_argument("--parallel", type=int, default=2)
    ap.add_argument("--duration", type=float, default=1800.0)
    ap.add_argument("--speedup", type=float, default=30.0)
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--work", default="/tmp/original_matrix_queue")
    ap.add_argument("--summary", default=om.RUNS)
    ap.add_argument("--dry-run", action="store_true", help="print the plan and stop")
    a = ap.parse_args()
    for name, low in (("min_runs", 1), ("max_runs", 1), ("parallel", 1)):
        if getattr(a, name) < low:
            ap.error(f"argument --{name.replace('_', '-')}: must be >= {low}")
    a.orig_ws = os.path.abspath(a.orig_ws)
    a.summary = os.path.abspath(a.summary)
    os.makedirs(a.work, exist_ok=True)
    cells = plan(a)
    runs, last = existing(a.summary, a.duration)
    todo = sum(max(0, a.min_runs - len(runs.get(c, []))) for c in cells)
    print(f"{len(cells)} cells, {todo} runs to give every cell {a.min_runs} "
          f"({sum(1 for c in cells if len(runs.get(c, [])) >= a.min_runs)} cells complete)",
          flush=True)
    if a.dry_run:
        for c in cells:
            print(" ", *c, len(runs.get(c, [])))
        return 0
    busy, pending, tries = set(), {}, {}
    next_index = {c: last.get(c, -1) + 1 for c in cells}
    with ThreadPoolExecutor(a.parallel) as pool:
        while True:
            runs, _ = existing(a.summary, a.duration)
            # cells in priority order; one that has its first runs gets more at once, so
            # that a queue stopped part-way leaves finished cells; a cell whose runs keep
            # failing is given up after max-runs + 2 tries
            free = [c for c in cells if c not in busy and tries.get(c, 0) < a.max_runs + 2
                    and (len(runs.get(c, [])) < a.min_runs
                         or needs_more(runs.get(c, []), a.max_runs))]
            while free and len(pending) < a.parallel:
                c = free.pop(0)
                busy.add(c)
                tries[c] = tries.get(c, 0) + 1
                pending[pool.submit(one_run, a, c, next_index[c])] = c
                next_index[c] += 1
            if not pending:
                break
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                busy.discard(pending.pop(f))
                f.result()
    return 0


if __name__ == "__main__":
    sys.exit(main())
