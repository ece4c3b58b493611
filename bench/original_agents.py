#!/usr/bin/python3
"""Run the ORIGINAL patrolling_sim's C++ agents in this project's abstract world (or, with
``--nav spqrel_nav_lite``, on the full stack), with this project's monitor
(docs/fidelity.md, "The original's own agents in the abstract world").

The reference runs in tests/unit/data/original_runs/ are two per algorithm on grid only, too
few for a figure that spreads as widely from run to run as DTAP's maximum idleness. This script
makes more runs of the original's agents in the same world as our ROS-mode runs (by default
grid, 4 robots at vertices 0, 13, 20, 11, 600 sim s after GO; any shipped map and team size
with ``--map``/``--robots``/``--duration``, the robots at the project's default start
positions for that map and team, as graph mode and the reference campaign;
docs/abstract_world.md): the runner writes the experiment's launch file (``--dry-run``), the
script drops our agents from it, starts the world and the monitor with ``roslaunch`` on a
master of its own, and starts the original's agent executables beside them, each in its own
session, with the arguments the original's launcher gives them (MSP its route file
``MSP/<map>/<map>_<N>_<id>``, GBS, SEBS and CBLS the team size). It stops only what it
started.

The agents read their graph from their own package. Where the original's graph file differs
from this project's (move_base_arena: this project moved vertex 0 and fixed one edge cost,
maps/README.md), they would patrol another graph than the world and monitor; so the agents
run from an overlay of their package (symbolic links to it, made under the output folder and
first on ROS_PACKAGE_PATH) whose graph for the map is this project's. ``--their-graph``
turns that off. No file of the original is changed.

``--summary FILE`` appends one compact row per run to a CSV (tests/unit/original_matrix.py,
``COLUMNS``): the figures, the visits per vertex, the pace and the load when the run began,
and which agents' processes had ended before the run did (their robots stood still).

The original's agents are not part of this repository. Build them yourself from the
original's public source (version 2.2.4) in a catkin workspace of their own, package name
``patrolling_sim`` (the agents find their graph through that name):
``bench/build_original_agents.sh SRC WS`` does it with the flags Debian 12 needs
(docs/fidelity.md). Because both packages are called ``patrolling_sim``,
the agents run with their workspace's environment and the world and monitor with ours.

With ``--ours shared|separate`` every run of the original is followed by a run of our agents
(seed = run index), so that both see the same machine load.

Usage:
    bench/original_agents.py --orig-ws PATH --alg DTAP [--map grid] [--robots 4]
                             [--duration 600] [--runs 20] [--first 0] [--speedup 30]
                             [--nav abstract|spqrel_nav_lite [--loc fake_localization|AMCL]]
                             [--ours separate [--ours-only]] [--out DIR] [--json FILE]
                             [--summary CSV]
"""
import argparse
import filecmp
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
sys.path.insert(0, os.path.join(ROOT, "tests", "unit"))
sys.path.insert(0, os.path.join(ROOT, "src", "spqrel_nav_lite", "src"))
from abstract_runs import (DURATION, MAP, ROBOTS, START, AbstractRun,  # noqa: E402
                           read_results, run_abstract)
import original_matrix  # noqa: E402
from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.runner.proctree import ProcessTree  # noqa: E402
from patrolling_sim.runner.rosenv import experiment_env, free_port, sourced_env  # noqa: E402

#: our short name -> the original's agent executable
BINARIES = {"RAND": "Random", "CR": "Conscientious_Reactive",
            "HCR": "Heuristic_Conscientious_Reactive", "HPCC": "Conscientious_Cognitive",
            "CGG": "Cyclic", "MSP": "MSP", "GBS": "GBS", "SEBS": "SEBS", "CBLS": "CBLS",
            "DTAG": "DTAGreedy", "DTAP": "DTASSIPart", "DTASSI": "DTASSI"}
#: the agents to which the original's launcher passes the team size
TEAM_SIZE_ARG = ("GBS", "SEBS", "CBLS")
#: wall s to wait at least for a run before it is stopped and reported (x30, 600 s: about
#: 30 s); a longer run gets its duration in wall s (run_limit): slower than real time on
#: average, it is taken to be stuck (DTAP with 8 robots, whose holds are many, reached x1.9
#: beside other runs, 1800 s in 950 wall s)
RUN_LIMIT = 900.0


def run_limit(duration):
    """Wall s a run of ``duration`` sim s may take before it is stopped."""
    return max(RUN_LIMIT, float(duration))


#: wall s after the agents start within which the first visit must come: now and then some
#: of the original's agents never report that they found their move_base server (roscpp's
#: actionlib under sim time), the monitor waits for them for good, and the run is stopped
START_LIMIT = 120.0


def world_launch(alg, seed, speedup, results_dir, env, exp):
    """Write the experiment's launch file with the runner (``--dry-run``) and a copy without
    our agents; return the copy's path. ``exp``: (map, robots, duration, dead robot
    timeout, the runner's world arguments, e.g. ``--nav abstract``)."""
    map_name, robots, duration, dead, world = exp
    cmd = ["/usr/bin/python3", START, "--map", map_name, "--robots", str(robots), "--alg", alg,
           *world, "--timeout", f"{duration:g}", "--speedup", f"{speedup:g}",
           "--processes", "separate", "--seed", str(seed), "--results-dir", results_dir,
           "--dead-robot-timeout", f"{dead:g}", "--dry-run"]
    r = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True)
    m = re.search(r"launch file: (\S+)", r.stdout)
    if r.returncode != 0 or not m:
        raise RuntimeError(f"runner --dry-run failed ({r.returncode}): {r.stdout[-500:]}")
    with open(m.group(1), encoding="utf-8") as f:
        xml = f.read()
    xml, n = re.subn(r'  <node pkg="patrolling_sim" type="patrol_agent".*?</node>\n', "", xml,
                     flags=re.S)
    if n != robots:
        raise RuntimeError(f"{m.group(1)}: expected {robots} agent nodes, found {n}")
    # the original's agents sleep on ROS time while they start: no start hold for them
    xml, n = re.subn(r'    <param name="start_wait" value="[^"]*"/>\n', "", xml)
    if n != int(world[-1] == "abstract"):
        raise RuntimeError(f"{m.group(1)}: expected the abstract world's start_wait, found {n}")
    path = m.group(1).replace("_experiment.launch", "_world_monitor.launch")
    with open(path, "w", encoding="utf-8") as f:
        f.write(xml)
    return path


def package_overlay(ws, map_name, out):
    """The folder holding the agents' package: the original's, or, when its graph of
    ``map_name`` differs from ours, an overlay under ``out`` (links to every entry of the
    original's package, and a ``maps/<map>`` whose graph file is ours). Returns (the folder
    to put first on ROS_PACKAGE_PATH or None, the package path)."""
    pkg = os.path.join(ws, "src", "patrolling_sim")
    theirs = os.path.join(pkg, "maps", map_name, f"{map_name}.graph")
    ours = paths.map_files(map_name)[1]
    if os.path.isfile(theirs) and filecmp.cmp(theirs, ours, shallow=False):
        return None, pkg
    root = os.path.join(out, "package_overlay")
    ovl = os.path.join(root, "patrolling_sim")
    shutil.rmtree(root, ignore_errors=True)
    os.makedirs(os.path.join(ovl, "maps", map_name))
    for e in os.listdir(pkg):
        if e != "maps":
            os.symlink(os.path.join(pkg, e), os.path.join(ovl, e))
    for e in os.listdir(os.path.join(pkg, "maps")):
        if e != map_name:
            os.symlink(os.path.join(pkg, "maps", e), os.path.join(ovl, "maps", e))
    src = os.path.join(pkg, "maps", map_name)
    for e in os.listdir(src) if os.path.isdir(src) else []:
        if e != f"{map_name}.graph":
            os.symlink(os.path.join(src, e), os.path.join(ovl, "maps", map_name, e))
    shutil.copyfile(ours, os.path.join(ovl, "maps", map_name, f"{map_name}.graph"))
    print(f"  the original's {map_name} graph differs from ours: its agents read ours "
          f"through {ovl}", flush=True)
    return root, ovl


def agent_args(alg, map_name, robot, robots):
    """The arguments the original's launcher gives agent ``robot`` (after ``__name``)."""
    if alg == "MSP":
        return [map_name, str(robot), f"MSP/{map_name}/{map_name}_{robots}_{robot}"]
    if alg in TEAM_SIZE_ARG:
        return [map_name, str(robot), str(robots)]
    return [map_name, str(robot)]


def stop(proc, grace=5.0):
    """Stop ``proc`` and what it started (SIGINT, then SIGTERM, then SIGKILL)."""
    if proc.poll() is None:
        ProcessTree(proc.pid).stop(grace)
    proc.wait()


def wait_sim_time(world, env, log):
    """Wait until the world's launch has set /use_sim_time (the agents read it at start)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < 60:
        r = subprocess.run(["rosparam", "get", "/use_sim_time"], env=env,
                           capture_output=True, text=True)
        if r.returncode == 0 and r.stdout.strip() == "true":
            return
        if world.poll() is not None:
            raise RuntimeError(f"roslaunch exited {world.returncode}, see {log}")
        time.sleep(0.3)
    raise RuntimeError(f"/use_sim_time not set after 60 s, see {log}")


def _visited(results_dir):
    """Some visit report is in the run's visits file (the run is under way)."""
    for path in glob.glob(os.path.join(results_dir, "**", "*_visits.csv"), recursive=True):
        with open(path, encoding="utf-8") as f:
            if f.readline() and f.readline():          # the header, then a visit
                return True
    return False


def run_original(orig_env, pkg, binary, alg, seed, speedup, results_dir, exp):
    """One run of the original's agents (``orig_env``: their workspace's environment,
    ``pkg``: their package folder, ``exp``: as :func:`world_launch`);
    returns an :class:`AbstractRun` with its figures."""
    map_name, robots = exp[:2]
    limit = run_limit(exp[2])
    port = free_port()
    ours = experiment_env(port, os.path.join(results_dir, "ros_home"))
    orig = dict(orig_env, **{k: ours[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_LOG_DIR",
                                                  "ROS_HOME")})
    launch = world_launch(alg, seed, speedup, results_dir, ours, exp)
    log = open(os.path.join(results_dir, "roslaunch.log"), "w")
    world = subprocess.Popen(["roslaunch", "-p", str(port), launch], env=ours, stdout=log,
                             stderr=subprocess.STDOUT, start_new_session=True)
    agents, logs = [], [log]
    try:
        wait_sim_time(world, ours, log.name)
        for i in range(robots):
            out = open(os.path.join(results_dir, f"agent_{i}.log"), "w")
            logs.append(out)
            # the original's agents change to their package folder and open their graph,
            # parameter and route files relative to it
            agents.append(subprocess.Popen(
                [binary, f"__name:=patrol_robot{i}", *agent_args(alg, map_name, i, robots)],
                cwd=pkg, env=orig, stdout=out, stderr=subprocess.STDOUT,
                start_new_session=True))
        # the monitor is required: its end ends the launch. The agents are stopped as soon as
        # its info.csv is there (its last file): a world shutting down while agents of another
        # launch are still connected sometimes did not exit on SIGINT (roslaunch then kills it)
        t0 = time.monotonic()
        exited, started = None, False
        while world.poll() is None and time.monotonic() - t0 < limit:
            started = started or _visited(results_dir)
            if not started and time.monotonic() - t0 > START_LIMIT:
                print(f"  run {seed}: no visit {START_LIMIT:.0f} wall s after the agents "
                      "started (some never announced), stopped", file=sys.stderr)
                break
            if glob.glob(os.path.join(results_dir, "**", "*_info.csv"), recursive=True):
                # agents whose process ended before the run did (the original's CBLS agent
                # exits when its learning step finds no arc): their robots stood still
                exited = [i for i, p in enumerate(agents) if p.poll() is not None]
                for p in agents:
                    stop(p)
                try:
                    world.wait(limit)
                except subprocess.TimeoutExpired:
                    pass
                break
            time.sleep(0.5)
        if world.poll() is None:
            print(f"  run {seed}: no end after {limit:.0f} s, stopped", file=sys.stderr)
    finally:
        for p in agents:
            stop(p)
        stop(world, grace=30.0)
        for f in logs:
            f.close()
    run = read_results(AbstractRun(world.returncode, ""), results_dir)
    run.exited = exited
    return run


def summary(label, runs):
    if not runs:
        return f"{label}: no complete run"
    parts = []
    for k, name in enumerate(("avg", "max", "visits")):
        v = [r[k] for r in runs]
        sd = statistics.stdev(v) if len(v) > 1 else 0.0
        parts.append(f"{name} {statistics.mean(v):.2f} (SD {sd:.2f}, {min(v):.1f}-{max(v):.1f})")
    return f"{label}, {len(runs)} runs: " + "; ".join(parts)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orig-ws", required=True,
                    help="catkin workspace with the original's agents built")
    ap.add_argument("--alg", required=True, help=f"one of {', '.join(BINARIES)}")
    ap.add_argument("--map", default=MAP, help=f"a shipped map (default {MAP})")
    ap.add_argument("--robots", type=int, default=ROBOTS, help=f"team size (default {ROBOTS})")
    ap.add_argument("--duration", type=float, default=DURATION,
                    help=f"sim s after GO (default {DURATION:g})")
    ap.add_argument("--dead-robot-timeout", type=float, default=0.0,
                    help="sim s without a visit report before the monitor ends the run as "
                         "FAIL (default 0: never, so a robot that stops patrolling shows in "
                         "the visits per vertex instead of ending the run; 300 is the "
                         "original monitor's rule)")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--first", type=int, default=0,
                    help="index of the first run (our seeds are the run indices)")
    ap.add_argument("--speedup", type=float, default=30.0)
    ap.add_argument("--ours", choices=("shared", "separate"),
                    help="after each run of the original, one of our agents (seed = index)")
    ap.add_argument("--ours-only", action="store_true",
                    help="with --ours: only our agents' runs (the original's were made before)")
    ap.add_argument("--nav", default="abstract", choices=("abstract", "spqrel_nav_lite"),
                    help="the world: the abstract world (default) or the full stack (the "
                    "Box2D simulator and this project's navigation, one per robot)")
    ap.add_argument("--loc", default="fake_localization",
                    choices=("fake_localization", "AMCL"),
                    help="the full stack's localiser (default fake_localization)")
    ap.add_argument("--their-graph", action="store_true",
                    help="the agents read the original's own graph file even where it differs "
                         "from ours")
    ap.add_argument("--out", help="keep every run's files here (default: a temporary folder)")
    ap.add_argument("--json", help="write the figures of every run here")
    ap.add_argument("--summary", help="append one compact row per run to this CSV")
    a = ap.parse_args()
    if a.alg not in BINARIES:
        ap.error(f"argument --alg: unknown algorithm {a.alg!r} (one of {', '.join(BINARIES)})")
    for name, low in (("runs", 1), ("first", 0), ("robots", 1)):
        if getattr(a, name) < low:
            ap.error(f"argument --{name}: must be >= {low}, got {getattr(a, name)}")
    if a.ours_only and not a.ours:
        ap.error("argument --ours-only: needs --ours")
    if a.ours and a.nav != "abstract":
        ap.error("argument --ours: runs of ours beside the original's in the abstract world "
                 "only (run the full stack's with scripts/start_experiments.py)")
    for name in ("speedup", "duration"):
        if getattr(a, name) <= 0:
            ap.error(f"argument --{name}: must be > 0, got {getattr(a, name):g}")
    ws = os.path.abspath(a.orig_ws)
    if not os.path.isfile(os.path.join(ws, "devel", "setup.bash")):
        ap.error(f"argument --orig-ws: {ws}: no devel/setup.bash (not a built workspace)")
    binary = os.path.join(ws, "devel", "lib", "patrolling_sim", BINARIES[a.alg])
    if not os.access(binary, os.X_OK):
        ap.error(f"argument --orig-ws: {binary}: the original's {a.alg} agent is not built")
    if a.alg == "MSP":
        for i in range(a.robots):
            route = agent_args("MSP", a.map, i, a.robots)[2]
            f = os.path.join(ws, "src", "patrolling_sim", *route.split("/"))
            if not os.path.isfile(f):
                ap.error(f"argument --map/--robots: the original ships no MSP route file {f}")
    return a, ws, binary


def one_run(a, who, k, d, ctx):
    """Run ``who`` (original / ours) with index ``k`` in folder ``d``; print its figures and
    append its summary row; returns the run (an AbstractRun)."""
    exp = (a.map, a.robots, a.duration, a.dead_robot_timeout,
           ["--nav", a.nav] + (["--loc", a.loc] if a.nav != "abstract" else []))
    load1 = os.getloadavg()[0]
    if who == "original":
        r = run_original(ctx["env"], ctx["pkg"], ctx["binary"], a.alg, k, a.speedup, d, exp)
    else:
        r = run_abstract(a.alg, k, d, processes=a.ours, speedup=a.speedup, duration=a.duration,
                         map_name=a.map, robots=a.robots,
                         extra=("--dead-robot-timeout", f"{a.dead_robot_timeout:g}"))
    ok = r.complete(a.duration)
    pace = (f", pace x{r.info['sim_duration'] / r.info['real_duration']:.1f}"
            if r.info and r.info["real_duration"] > 0 else "")
    print(f"{who} run {k} (load {load1:.2f}{pace}): "
          + (f"avg {r.avg:.2f} max {r.max:.1f} visits {r.visits}" if ok else
             f"incomplete (exit {r.exit_code}, info {r.info}), left out"), flush=True)
    if not ok and r.output:
        with open(os.path.join(d, "runner_output.txt"), "w", encoding="utf-8") as f:
            f.write(r.output)
    if a.summary:
        agents = "original" if who == "original" else f"ours_{a.ours}"
        row = original_matrix.summary_row(d, agents, a.alg, k, a.speedup, a.duration, load1,
                                          exited=getattr(r, "exited", None))
        if row:
            original_matrix.append_rows(a.summary, [row])
    return r


def main():
    a, ws, binary = parse_args()
    out = os.path.abspath(a.out) if a.out else tempfile.mkdtemp(prefix="original_agents_")
    os.makedirs(out, exist_ok=True)
    print(f"{a.alg} ({BINARIES[a.alg]}), {a.map}, {a.robots} robots, {a.duration:g} s after "
          f"GO, x{a.speedup:g}, files under {out}", flush=True)
    env = sourced_env(os.path.join(ws, "devel", "setup.bash"))
    overlay, pkg = (None, os.path.join(ws, "src", "patrolling_sim")) if a.their_graph \
        else package_overlay(ws, a.map, out)
    if overlay:
        env["ROS_PACKAGE_PATH"] = overlay + os.pathsep + env.get("ROS_PACKAGE_PATH", "")
    ctx = {"env": env, "pkg": pkg, "binary": binary}
    raw = {"original": [], "ours": []}
    for k in range(a.first, a.first + a.runs):
        for who in ("ours",) if a.ours_only else ("original", "ours") if a.ours else (
                "original",):
            d = os.path.join(out, f"{who}_{k:02d}")
            os.makedirs(d, exist_ok=True)
            r = one_run(a, who, k, d, ctx)
            if r.complete(a.duration):
                raw[who].append(r.figures())
    if not a.ours_only:
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
