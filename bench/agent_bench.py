#!/usr/bin/python3
"""Benchmark of the ROS nodes: CPU of N patrol_agent nodes + monitor against the stand-in
move_base (fake_move_base), no simulator.

For each algorithm it starts, with ``roslaunch`` on a free port (own master):
fake_move_base (``--speed`` m/s, 10 Hz feedback), the monitor (``~timeout`` = duration) and
N agents on ``--map`` with computed start positions, ``/use_sim_time`` false (sim time =
wall time). After GO it measures the CPU time (utime+stime from /proc) of every process of
the launch over ``--duration`` s and reports, in % of one core: the sum and the mean of the
agents, the monitor, fake_move_base, and rosmaster+rosout+roslaunch. It also checks the run
(info.csv termination TIMEOUT, visits, cycles) so that a broken algorithm shows up.

Usage:
    bench/agent_bench.py [--map grid] [--robots 12] [--algs CR DTAP] [--duration 60]
                         [--speed 1.0] [--out bench/notes/agent.md]
"""
import argparse
import datetime
import glob
import os
import platform
import socket
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))
from procstat import cpu_ticks  # noqa: E402

CLK = os.sysconf("SC_CLK_TCK")
GO_WAITER = """
import sys, threading, rospy
from std_msgs.msg import Int16MultiArray
go = threading.Event()
rospy.init_node("bench_go_waiter", anonymous=True)
rospy.Subscriber("/results", Int16MultiArray,
                 lambda m: list(m.data) == [-1, 10, 100] and go.set(), queue_size=1000)
sys.exit(0 if go.wait(170) else 1)
"""


def ros_env():
    """Environment of ``devel/setup.bash`` with /usr/bin first on PATH."""
    setup = os.path.join(ROOT, "devel", "setup.bash")
    if not os.path.isfile(setup):
        sys.exit(f"agent_bench: error: {setup} not found (run make build first)")
    out = subprocess.run(["bash", "-c", f"source {setup} && env -0"], capture_output=True,
                         check=True).stdout.decode()
    env = dict(kv.split("=", 1) for kv in out.split("\0") if "=" in kv)
    env["PATH"] = "/usr/bin:/bin:" + env.get("PATH", "")
    return env


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def children_map():
    kids = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d))
    return kids


def descendants(root):
    kids, out, todo = children_map(), [], [root]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(kids.get(p, []))
    return out


def classify(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            cmd = f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return None
    for key, name in (("patrol_agent", "agents"), ("/monitor", "monitor"),
                      ("fake_move_base", "fake_move_base"), ("rosmaster", "ros"),
                      ("rosout", "ros"), ("roslaunch", "ros")):
        if key in cmd:
            return name
    return None


def make_launch(args, alg, n, results_dir):
    from patrolling_sim.common import paths
    from patrolling_sim.model import map_bundle
    from patrolling_sim.model.graph import PatrolGraph
    from patrolling_sim.startpos.resolve import start_positions
    occ, G = map_bundle.load_map_bundle(args.map)
    pg = PatrolGraph(G)
    pos, _ = start_positions(paths.map_name(args.map), n, pg, occ)
    flat = ", ".join(f"{x:.4f}, {y:.4f}" for x, y in pos)
    L = ["<launch>",
         '  <param name="/use_sim_time" value="false"/>',
         f'  <param name="/goal_reached_wait" value="{args.gwait}"/>',
         '  <param name="/communication_delay" value="0.0"/>',
         f"  <rosparam param=\"/initial_pos\">[{flat}]</rosparam>",
         '  <node pkg="patrolling_sim" type="fake_move_base.py" name="fake_move_base">',
         f'    <param name="speed" value="{args.speed}"/> <param name="rate" value="10"/>',
         "  </node>",
         f'  <node pkg="patrolling_sim" type="monitor" name="monitor" required="true" '
         f'args="{args.map} {alg} {n}">',
         f'    <param name="results_dir" value="{results_dir}"/>',
         f'    <param name="timeout" value="{args.duration + 10}"/>',
         "  </node>"]
    for i in range(n):
        L += [f'  <node pkg="patrolling_sim" type="patrol_agent" name="patrol_robot{i}" '
              f'args="{args.map} {i}">',
              f'    <param name="algorithm" value="{alg}"/> <param name="team_size" '
              f'value="{n}"/> <param name="seed" value="{i}"/>',
              "  </node>"]
    L.append("</launch>")
    return "\n".join(L) + "\n"


def run_one(args, alg, n):
    tmp = tempfile.mkdtemp(prefix=f"agent_bench_{alg}_")
    results_dir = os.path.join(tmp, "results")
    launch = os.path.join(tmp, "bench.launch")
    with open(launch, "w") as f:
        f.write(make_launch(args, alg, n, results_dir))
    port = free_port()
    env = dict(ros_env(), ROS_MASTER_URI=f"http://localhost:{port}", ROS_HOME=tmp)
    log = open(os.path.join(tmp, "roslaunch.log"), "w")
    proc = subprocess.Popen(["roslaunch", "-p", str(port), launch], env=env, stdout=log,
                            stderr=subprocess.STDOUT, start_new_session=True)
    t_launch = time.time()
    try:
        # wait for the monitor's GO on /results (a helper node on this launch's master)
        waiter = subprocess.run(["/usr/bin/python3", "-c", GO_WAITER], env=env,
                                capture_output=True, text=True, timeout=180)
        if waiter.returncode != 0:
            raise RuntimeError(f"{alg}: no GO ({waiter.stderr.strip()[-300:]}; see "
                               f"{tmp}/roslaunch.log)")
        t_go = time.time() - t_launch
        pids = descendants(proc.pid)
        t0 = time.time()
        before = {p: cpu_ticks(p) for p in pids}
        time.sleep(args.duration)
        after = {p: cpu_ticks(p) for p in pids}
        wall = time.time() - t0
        use = {}
        for p in pids:
            kind = classify(p)
            if kind and before[p] is not None and after[p] is not None:
                use.setdefault(kind, []).append((after[p] - before[p]) / CLK / wall * 100.0)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, 2)
            proc.wait(timeout=30)
        log.close()
    infos = glob.glob(os.path.join(results_dir, "**", "*_info.csv"), recursive=True)
    info = open(infos[0]).read().strip().split(";") if infos else None
    agents = use.get("agents", [])
    return dict(alg=alg, n=n, go=t_go, agents_sum=sum(agents),
                agents_mean=sum(agents) / len(agents) if agents else 0.0,
                agents_max=max(agents) if agents else 0.0, n_agents=len(agents),
                monitor=sum(use.get("monitor", [])), fake=sum(use.get("fake_move_base", [])),
                ros=sum(use.get("ros", [])), info=info, tmp=tmp)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--map", default="grid")
    ap.add_argument("--robots", type=int, default=12)
    ap.add_argument("--algs", nargs="+", default=["CR"])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument("--gwait", type=float, default=0.0)
    ap.add_argument("--out", default=None, help="append a markdown table to this file")
    args = ap.parse_args()
    if args.robots < 1 or args.duration <= 0 or args.speed <= 0:
        ap.error("--robots, --duration and --speed must be positive")
    rows = []
    for alg in args.algs:
        r = run_one(args, alg, args.robots)
        info = r["info"]
        status = (f"{info[13]}, visits {info[19]}, cycles {info[21]}, avg idl {info[15]}"
                  if info else "NO info.csv")
        if r["n_agents"] != args.robots:
            status += f" (only {r['n_agents']} agent processes measured)"
        print(f"{alg}: agents {r['agents_sum']:.1f}% total ({r['agents_mean']:.2f}% mean, "
              f"{r['agents_max']:.2f}% max), monitor {r['monitor']:.1f}%, fake_move_base "
              f"{r['fake']:.1f}%, master/rosout/roslaunch {r['ros']:.1f}%; launch->GO "
              f"{r['go']:.1f} s; {status}", flush=True)
        rows.append((r, status))
    if args.out:
        host = platform.node()
        cpu = "unknown CPU"
        try:
            with open("/proc/cpuinfo") as f:
                cpu = next(ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name"))
        except (OSError, StopIteration):
            pass
        with open(args.out, "a") as f:
            f.write(f"\n### {args.map}, {args.robots} robots, {args.duration:.0f} s, "
                    f"speed {args.speed} m/s ({datetime.date.today()}, {host}, "
                    f"{os.cpu_count()} cores, {cpu})\n\n")
            f.write("| alg | agents total % | agent mean % | agent max % | monitor % | "
                    "fake_move_base % | master+rosout+roslaunch % | run |\n")
            f.write("|---|---|---|---|---|---|---|---|\n")
            for r, status in rows:
                f.write(f"| {r['alg']} | {r['agents_sum']:.1f} | {r['agents_mean']:.2f} | "
                        f"{r['agents_max']:.2f} | {r['monitor']:.1f} | {r['fake']:.1f} | "
                        f"{r['ros']:.1f} | {status} |\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
