#!/usr/bin/python3
"""Run the ORIGINAL patrolling_sim's C++ agents in this project's abstract world, with this
project's monitor (docs/fidelity.md, "The original's own agents in the abstract world").

The reference runs in tests/unit/data/original_runs/ are two per algorithm, too few for a
figure that spreads as widely from run to run as DTAP's maximum idleness. This script makes
more runs of the original's agents in the same world as our ROS-mode runs (grid, 4 robots at
vertices 0, 13, 20, 11, 600 sim s after GO, docs/abstract_world.md): the runner writes the
experiment's launch file (``--dry-run``), the script drops our agents from it, starts the world
and the monitor with ``roslaunch`` on a master of its own, and starts the original's agent
executables beside them, each in its own session. It stops only what it started.

The original's agents are not part of this repository. Build them yourself from the
original's public source (version 2.2.4) in a catkin workspace of their own, package name
``patrolling_sim`` (the agents find their graph through that name); see docs/fidelity.md
for the build flags Debian 12 needs. Because both packages are called ``patrolling_sim``,
the agents run with their workspace's environment and the world and monitor with ours.

With ``--ours shared|separate`` every run of the original is followed by a run of our agents
(seed = run index), so that both see the same machine load.

Usage:
    bench/original_agents.py --orig-ws PATH --alg DTAP [--runs 20] [--first 0] [--speedup 30]
                             [--ours separate] [--out DIR] [--json FILE]
"""
import argparse
import glob
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "ros"))
from abstract_runs import (DURATION, MAP, ROBOTS, START, AbstractRun,  # noqa: E402
                           read_results, run_abstract)
from patrolling_sim.runner.proctree import ProcessTree  # noqa: E402
from patrolling_sim.runner.rosenv import experiment_env, free_port, sourced_env  # noqa: E402

#: our short name -> the original's agent executable
BINARIES = {"RAND": "Random", "CR": "Conscientious_Reactive",
            "HCR": "Heuristic_Conscientious_Reactive", "HPCC": "Conscientious_Cognitive",
            "CGG": "Cyclic", "MSP": "MSP", "GBS": "GBS", "SEBS": "SEBS", "CBLS": "CBLS",
            "DTAG": "DTAGreedy", "DTAP": "DTASSIPart", "DTASSI": "DTASSI"}
#: wall s to wait for a run (x30: about 30 s) before it is stopped and reported
RUN_LIMIT = 900.0


def world_launch(alg, seed, speedup, results_dir, env):
    """Write the experiment's launch file with the runner (``--dry-run``) and a copy without
    our agents; return the copy's path."""
    cmd = ["/usr/bin/python3", START, "--map", MAP, "--robots", str(ROBOTS), "--alg", alg,
           "--nav", "abstract", "--timeout", f"{DURATION:g}", "--speedup", f"{speedup:g}",
           "--processes", "separate", "--seed", str(seed), "--results-dir", results_dir,
           "--dry-run"]
    r = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True)
    m = re.search(r"launch file: (\S+)", r.stdout)
    if r.returncode != 0 or not m:
        raise RuntimeError(f"runner --dry-run failed ({r.returncode}): {r.stdout[-500:]}")
    with open(m.group(1), encoding="utf-8") as f:
        xml = f.read()
    xml, n = re.subn(r'  <node pkg="patrolling_sim" type="patrol_agent".*?</node>\n', "", xml,
                     flags=re.S)
    if n != ROBOTS:
        raise RuntimeError(f"{m.group(1)}: expected {ROBOTS} agent nodes, found {n}")
    path = m.group(1).replace("_experiment.launch", "_world_monitor.launch")
    with open(path, "w", encoding="utf-8") as f:
        f.write(xml)
    return path


def stop(proc, grace=5.0):
    """Stop ``proc`` and what it started (SIGINT, then SIGTERM, then SIGKILL)."""
    if proc.poll() is None:
        ProcessTree(proc.pid).stop(grace)
    proc.wait()


def run_original(ws, orig_env, binary, alg, seed, speedup, results_dir):
    """One run of the original's agents (``orig_env``: their workspace's environment);
    returns an :class:`AbstractRun` with its figures."""
    port = free_port()
    ours = experiment_env(port, os.path.join(results_dir, "ros_home"))
    orig = dict(orig_env, **{k: ours[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_LOG_DIR",
                                                  "ROS_HOME")})
    launch = world_launch(alg, seed, speedup, results_dir, ours)
    log = open(os.path.join(results_dir, "roslaunch.log"), "w")
    world = subprocess.Popen(["roslaunch", "-p", str(port), launch], env=ours, stdout=log,
                             stderr=subprocess.STDOUT, start_new_session=True)
    agents, logs = [], [log]
    try:
        # the agents read /use_sim_time when they start: wait until the launch has set it
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60:
            r = subprocess.run(["rosparam", "get", "/use_sim_time"], env=ours,
                               capture_output=True, text=True)
            if r.returncode == 0 and r.stdout.strip() == "true":
                break
            if world.poll() is not None:
                raise RuntimeError(f"roslaunch exited {world.returncode}, see {log.name}")
            time.sleep(0.3)
        else:
            raise RuntimeError(f"/use_sim_time not set after 60 s, see {log.name}")
        pkg = os.path.join(ws, "src", "patrolling_sim")
        for i in range(ROBOTS):
            out = open(os.path.join(results_dir, f"agent_{i}.log"), "w")
            logs.append(out)
            # the original's agents read argv as (map, id, team size) and open their
            # parameter files relative to the working directory: its package folder
            agents.append(subprocess.Popen(
                [os.path.join(ws, "devel", "lib", "patrolling_sim", binary),
                 f"__name:=patrol_robot{i}", MAP, str(i), str(ROBOTS)],
                cwd=pkg, env=orig, stdout=out, stderr=subprocess.STDOUT,
                start_new_session=True))
        # the monitor is required: its end ends the launch. The agents are stopped as soon as
        # its info.csv is there (its last file): a world shutting down while agents of another
        # launch are still connected sometimes did not exit on SIGINT (roslaunch then kills it)
        t0 = time.monotonic()
        while world.poll() is None and time.monotonic() - t0 < RUN_LIMIT:
            if glob.glob(os.path.join(results_dir, "**", "*_info.csv"), recursive=True):
                for p in agents:
                    stop(p)
                try:
                    world.wait(RUN_LIMIT)
                except subprocess.TimeoutExpired:
                    pass
                break
            time.sleep(0.5)
        if world.poll() is None:
            print(f"  run {seed}: no end after {RUN_LIMIT:.0f} s, stopped", file=sys.stderr)
    finally:
        for p in agents:
            stop(p)
        stop(world, grace=30.0)
        for f in logs:
            f.close()
    return read_results(AbstractRun(world.returncode, ""), results_dir)


def summary(label, runs):
    if not runs:
        return f"{label}: no complete run"
    parts = []
    for k, name in enumerate(("avg", "max", "visits")):
        v = [r[k] for r in runs]
        sd = statistics.stdev(v) if len(v) > 1 else 0.0
        parts.append(f"{name} {statistics.mean(v):.2f} (SD {sd:.2f}, {min(v):.1f}-{max(v):.1f})")
    return f"{label}, {len(runs)} runs: " + "; ".join(parts)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orig-ws", required=True,
                    help="catkin workspace with the original's agents built")
    ap.add_argument("--alg", required=True, help=f"one of {', '.join(BINARIES)}")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--first", type=int, default=0,
                    help="index of the first run (our seeds are the run indices)")
    ap.add_argument("--speedup", type=float, default=30.0)
    ap.add_argument("--ours", choices=("shared", "separate"),
                    help="after each run of the original, one of our agents (seed = index)")
    ap.add_argument("--out", help="keep every run's files here (default: a temporary folder)")
    ap.add_argument("--json", help="write the figures of every run here")
    a = ap.parse_args()
    if a.alg not in BINARIES:
        ap.error(f"argument --alg: unknown algorithm {a.alg!r} (one of {', '.join(BINARIES)})")
    if a.runs < 1:
        ap.error(f"argument --runs: must be >= 1, got {a.runs}")
    if a.first < 0:
        ap.error(f"argument --first: must be >= 0, got {a.first}")
    if a.speedup <= 0:
        ap.error(f"argument --speedup: must be > 0, got {a.speedup:g}")
    ws = os.path.abspath(a.orig_ws)
    binary = os.path.join(ws, "devel", "lib", "patrolling_sim", BINARIES[a.alg])
    if not os.path.isfile(os.path.join(ws, "devel", "setup.bash")):
        ap.error(f"argument --orig-ws: {ws}: no devel/setup.bash (not a built workspace)")
    if not os.access(binary, os.X_OK):
        ap.error(f"argument --orig-ws: {binary}: the original's {a.alg} agent is not built")
    out = os.path.abspath(a.out) if a.out else tempfile.mkdtemp(prefix="original_agents_")
    os.makedirs(out, exist_ok=True)
    print(f"{a.alg} ({BINARIES[a.alg]}), grid, {ROBOTS} robots, {DURATION:g} s after GO, "
          f"x{a.speedup:g}, files under {out}", flush=True)
    orig_env = sourced_env(os.path.join(ws, "devel", "setup.bash"))
    raw = {"original": [], "ours": []}
    for k in range(a.first, a.first + a.runs):
        runs = [("original", lambda d: run_original(ws, orig_env, BINARIES[a.alg], a.alg, k,
                                                    a.speedup, d))]
        if a.ours:
            runs.append(("ours", lambda d: run_abstract(a.alg, k, d, processes=a.ours,
                                                        speedup=a.speedup)))
        for who, run in runs:
            d = os.path.join(out, f"{who}_{k:02d}")
            os.makedirs(d, exist_ok=True)
            r = run(d)
            ok = r.complete()
            print(f"{who} run {k}: " + (f"avg {r.avg:.2f} max {r.max:.1f} visits {r.visits}"
                                        if ok else f"incomplete (exit {r.exit_code}, info "
                                                   f"{r.info}), left out"), flush=True)
            if ok:
                raw[who].append(r.figures())
            elif r.output:
                with open(os.path.join(d, "runner_output.txt"), "w", encoding="utf-8") as f:
                    f.write(r.output)
    print(summary("original's agents", raw["original"]))
    if a.ours:
        print(summary(f"our agents (--processes {a.ours})", raw["ours"]))
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(raw, f)
    if not a.out:
        shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
