#!/usr/bin/python3
"""Full-experiment benchmark: sustained real-time factor, launch-to-GO time, CPU and memory.

For each configuration (grid; 4, 8, 12 robots; fake localisation and the AMCL-equivalent
localiser) it runs ``scripts/start_experiments.py`` headless with the given speed-up
(default: as fast as possible) and a sim-time timeout, and samples the experiment's whole
process tree from /proc once per second:

- launch-to-GO: wall seconds from start to the monitor's GO (printed by the runner);
- sustained RTF: (sim time at end - sim time at GO) / (wall time at end - wall time at GO),
  from the simulator's own log lines (each carries its wall and sim stamps), after GO;
- CPU: mean total CPU of the tree over the run after GO, in % of one core;
- memory: peak total PSS (proportional set size) of the tree, MB, and the peak PSS of the
  navigation processes (robot_nav, amcl, fake_localization, move_base or nav_host) per robot;
- CPU-seconds per simulated second, whole tree and navigation processes only (CPU time
  after GO over the sim time it
  advanced): unlike the pace, it does not depend on what else loads the machine;
- patrol quality, from the run's info.csv: visits per robot per simulated minute, average
  idleness, interferences, and the simulator's robot-robot contacts. A pace the navigation
  cannot follow shows up here first (fewer visits, more interferences), so compare these
  with the same team at speed-up 1.

Usage:
    bench/runner_bench.py [--robots 4 8 12] [--loc fake_localization AMCL] [--timeout 300]
                          [--speedup 4] [--processes shared|separate|pooled[:K]|
                          pooled-separate[:K]] [--map grid] [--out bench/notes/runner.md]
"""
import argparse
import glob
import os
import re
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))
from patrolling_sim.runner.proctree import ProcessTree  # noqa: E402
from procstat import cpu_ticks, pss_kb  # noqa: E402

CLK = os.sysconf("SC_CLK_TCK")
PROGRESS = re.compile(r"progress: sim ([\d.]+) s \| go (\w+)")
SIM_LOG = re.compile(r"\[ INFO\] \[([\d.]+), ([\d.]+)\]: stage2d: sim time .*contacts wall "
                     r"(\d+) robot (\d+)(?:, stale commands ([\d.]+)%)?")


NAV_NODES = ("nav_host", "robot_nav", "/move_base", "/amcl", "/fake_localization")


def is_nav(pid):
    """True if the process is one of our navigation nodes (from its command line)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = f.read().split(b"\0")
    except OSError:
        return False
    return any(a.decode(errors="replace").endswith(NAV_NODES) for a in argv[:3])


def sim_log(results_dir, robots, alg, map_name="grid"):
    """[(wall, sim, wall contacts, robot contacts)] from the newest run's simulator log."""
    logs = sorted(glob.glob(os.path.join(results_dir, f"{map_name}_{robots}", alg, "*", "*_logs",
                                         "roslaunch.log")), key=os.path.getmtime)
    out = []
    if logs:
        with open(logs[-1], errors="replace") as f:
            for line in f:
                m = SIM_LOG.search(line)
                if m:
                    out.append((float(m.group(1)), float(m.group(2)), int(m.group(3)),
                                int(m.group(4)), float(m.group(5) or "nan")))
    return out


def run_one(robots, loc, timeout, speedup, alg, results_dir, processes, map_name="grid"):
    cmd = [sys.executable, os.path.join(ROOT, "scripts", "start_experiments.py"), "--headless",
           "--map", map_name, "--force", "--robots", str(robots), "--alg", alg, "--loc", loc,
           "--timeout", str(timeout), "--speedup", str(speedup), "--results-dir", results_dir,
           "--processes", processes]
    wall_start = time.time()
    t0 = time.monotonic()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         start_new_session=True)
    tree = ProcessTree(p.pid)
    samples = []            # (wall, cumulative cpu ticks of the tree, pss kb, nav pss kb)
    seen = {}               # pid -> last cpu ticks (per-process deltas: exits don't subtract)
    cum = 0
    cum_nav = 0
    nav_pids = {}            # pid -> is a navigation process
    state = {"go_wall": None, "go_sim": None, "last": None, "lines": []}

    def reader():
        for line in p.stdout:
            state["lines"].append(line.rstrip())
            m = PROGRESS.search(line)
            now = time.monotonic() - t0
            if m:
                sim, go = float(m.group(1)), m.group(2) == "yes"
                if go and state["go_wall"] is None:
                    state["go_wall"], state["go_sim"] = now, sim
                if go:
                    state["last"] = (now, sim)
            if line.startswith("GO after"):
                state["go_reported"] = float(line.split()[2])
    th = threading.Thread(target=reader, daemon=True)
    th.start()
    while p.poll() is None:
        tree.refresh()
        pids = tree.alive()
        for x in pids:
            t = cpu_ticks(x)
            if t is None:                   # exited since the listing
                continue
            cum += max(0, t - seen.get(x, 0))
            if not nav_pids.get(x):
                # not cached while False: a process seen between its fork and its exec still
                # shows its parent's command line (a nav_host can be missed otherwise)
                nav_pids[x] = is_nav(x)
            if nav_pids[x]:
                cum_nav += max(0, t - seen.get(x, 0))
            seen[x] = t
        pss = {x: pss_kb(x) for x in pids}
        samples.append((time.monotonic() - t0, cum, sum(pss.values()),
                        sum(v for x, v in pss.items() if nav_pids.get(x)), cum_nav))
        time.sleep(1.0)
    th.join(timeout=5)
    res = {"robots": robots, "loc": loc, "exit": p.returncode, "go": state.get("go_reported"),
           "processes": processes}
    if state["go_wall"] is not None:
        after = [s for s in samples if s[0] >= state["go_wall"]]
        if len(after) >= 2:
            span = after[-1][0] - after[0][0]
            res["cpu"] = 100.0 * (after[-1][1] - after[0][1]) / CLK / span
            res["nav_cpu"] = 100.0 * (after[-1][4] - after[0][4]) / CLK / span
        # RTF from the simulator's own stamped log lines after GO (+ a few s of settling)
        go_abs = wall_start + state["go_wall"] + 3.0
        pts = [x for x in sim_log(results_dir, robots, alg, map_name) if x[0] >= go_abs]
        if len(pts) >= 2:
            res["rtf"] = (pts[-1][1] - pts[0][1]) / (pts[-1][0] - pts[0][0])
            if "cpu" in res:       # CPU-seconds per simulated second
                res["cpu_per_sim_s"] = res["cpu"] / 100.0 / res["rtf"]
                res["nav_cpu_per_sim_s"] = res["nav_cpu"] / 100.0 / res["rtf"]
            res["contacts"] = pts[-1][3]
            res["stale"] = pts[-1][4]
    res["pss_mb"] = max((s[2] for s in samples), default=0) / 1024.0
    res["nav_pss_mb"] = max((s[3] for s in samples), default=0) / 1024.0 / robots
    res["tail"] = state["lines"][-3:]
    # patrol quality (from the run's info.csv): visits per robot per simulated minute,
    # average idleness and interferences; they degrade when the navigation cannot keep up
    infos = sorted(glob.glob(os.path.join(results_dir, f"{map_name}_{robots}", alg, "*",
                                          "*_info.csv")), key=os.path.getmtime)
    if infos:
        f = open(infos[-1]).read().strip().split(";")
        sim_s, visits = float(f[10]), int(f[19])
        res["vpm"] = (visits + 25) / robots / (sim_s / 60.0) if sim_s > 0 else float("nan")
        # empty in a run too short for any vertex to be visited twice
        res["idl"] = float(f[15]) if f[15].strip() else float("nan")
        res["interf"] = int(f[12])
    res["load"] = os.getloadavg()[0]
    # the runner's memory estimate for this run (patrolling_sim.experiment.validation), to
    # compare with the measured peak PSS when its figures are updated
    from patrolling_sim.experiment import validation
    res["estimate_mb"] = validation.memory_estimate_mb(
        robots, processes, *validation.map_memory_figures(map_name))
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[4, 8, 12])
    ap.add_argument("--loc", nargs="+", default=["fake_localization", "AMCL"])
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("--speedup", type=float, default=4.0)
    ap.add_argument("--processes", default="shared",
                    help="shared | separate | pooled[:K] | pooled-separate[:K]")
    ap.add_argument("--map", default="grid")
    ap.add_argument("--alg", default="CGG")
    ap.add_argument("--out", help="append a markdown table to this file")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for loc in args.loc:
            for n in args.robots:
                r = run_one(n, loc, args.timeout, args.speedup, args.alg, tmp, args.processes,
                            args.map)
                rows.append(r)
                nan = float("nan")
                print(f"{loc:18s} N={n:3d} exit={r['exit']} GO={r.get('go')} s "
                      f"RTF={r.get('rtf', nan):.2f} CPU={r.get('cpu', nan):.0f}% "
                      f"PSS={r['pss_mb']:.0f} MB (runner's estimate {r['estimate_mb']:.0f}) "
                      f"nav PSS/robot={r['nav_pss_mb']:.0f} MB "
                      f"CPU-s/sim-s={r.get('cpu_per_sim_s', nan):.3f} "
                      f"(nav {r.get('nav_cpu_per_sim_s', nan):.3f}) "
                      f"visits/robot/min={r.get('vpm', nan):.1f} "
                      f"avg idl={r.get('idl', nan):.1f} s interferences={r.get('interf')} "
                      f"contacts={r.get('contacts')} stale cmds={r.get('stale', nan):.1f}% "
                      f"load={r['load']:.1f}", flush=True)
                if r["exit"] != 0:
                    print("   " + "\n   ".join(r["tail"]))
    if args.out:
        with open(args.out, "a") as f:
            f.write(f"\n{time.strftime('%Y-%m-%d %H:%M')} `bench/runner_bench.py --timeout "
                    f"{args.timeout:g} --speedup {args.speedup:g} --alg {args.alg} --processes "
                    f"{args.processes} --map {args.map}` on {os.uname().nodename} "
                    f"({os.cpu_count()} cores)\n\n")
            f.write("| localisation | robots | exit | launch to GO (s) | sustained RTF | "
                    "CPU (% of a core) | CPU-s per sim-s (nav) | peak PSS (MB) | "
                    "runner's estimate (MB) | nav PSS/robot (MB) | visits/robot/sim-min | "
                    "avg idleness (s) | interferences | robot contacts | stale commands (%) | "
                    "load avg |\n")
            f.write("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
            nan = float("nan")
            for r in rows:
                f.write(f"| {r['loc']} | {r['robots']} | {r['exit']} | {r.get('go')} | "
                        f"{r.get('rtf', nan):.2f} | {r.get('cpu', nan):.0f} | "
                        f"{r.get('cpu_per_sim_s', nan):.3f} ({r.get('nav_cpu_per_sim_s', nan):.3f})"
                        f" | {r['pss_mb']:.0f} | {r['estimate_mb']:.0f} | "
                        f"{r['nav_pss_mb']:.0f} | {r.get('vpm', nan):.1f} | "
                        f"{r.get('idl', nan):.1f} | "
                        f"{r.get('interf')} | {r.get('contacts')} | {r.get('stale', nan):.1f} | "
                        f"{r['load']:.1f} |\n")


if __name__ == "__main__":
    main()
