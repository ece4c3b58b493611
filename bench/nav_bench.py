#!/usr/bin/python3
"""spqrel_nav_lite benchmark.

1. Localiser update time (predict + 30-beam likelihood field + resample + estimate), median
   and p95, with 100 and 500 particles, on grid and DIAG_floor1 (pure numpy, no ROS).
2. Global planning on broughton and DIAG_floor1: planner build time, and the time to plan
   the longest goal (farthest pair of patrol vertices) with a fresh navigation function.
3. Live run (ROS, own master): patrol_stage2d at 1x with N robots on grid, each with
   robot_nav.launch (fake_localization, then AMCL; separate nodes, then the combined
   robot_nav process); every robot drives to random patrol vertices for --duration wall
   seconds. CPU of each node is sampled from /proc and reported per robot (localiser,
   move_base, both together), plus the goal outcomes.

Usage: bench/nav_bench.py [--robots 4] [--duration 60] [--skip-live] [--out bench/notes/nav.md]
"""
import argparse
import math
import os
import platform
import random
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for p in ("patrolling_sim", "spqrel_nav_lite"):
    sys.path.insert(0, os.path.join(ROOT, "src", p, "src"))
from patrolling_sim.model.graph import PatrolGraph  # noqa: E402
from spqrel_nav_lite.mapio import load_map  # noqa: E402
from spqrel_nav_lite.particle_filter import LikelihoodField, ParticleFilter  # noqa: E402
from spqrel_nav_lite.planner import GlobalPlanner, path_length  # noqa: E402
from procstat import cpu_ticks  # noqa: E402

CLK = os.sysconf("SC_CLK_TCK")


def map_paths(name):
    return (os.path.join(ROOT, "maps", name, name + ".yaml"),
            os.path.join(ROOT, "maps", name, name + ".graph"))


def bench_localiser(name, n_particles, updates=300):
    yaml_path, graph_path = map_paths(name)
    m = load_map(yaml_path)
    g = PatrolGraph.load(graph_path)
    field = LikelihoodField(m)
    rng = np.random.default_rng(0)
    pf = ParticleFilter(field, n_particles, n_particles, rng=rng)
    v = g.pos[0]
    pf.init_gaussian((v[0], v[1], 0.0))
    angles = np.linspace(-2.36, 2.36, 30)
    ranges = rng.uniform(0.5, 8.0, 30)
    times = []
    odom = (0.0, 0.0, 0.0)
    for k in range(updates):
        new = (odom[0] + 0.2 * math.cos(odom[2]), odom[1] + 0.2 * math.sin(odom[2]), odom[2] + 0.05)
        t0 = time.perf_counter()
        pf.predict(odom, new)
        pf.update(ranges, angles)
        pf.estimate()
        pf.resample()
        times.append(time.perf_counter() - t0)
        odom = new
    t = np.array(times) * 1e3
    return float(np.median(t)), float(np.percentile(t, 95))


def bench_planner(name):
    yaml_path, graph_path = map_paths(name)
    m = load_map(yaml_path)
    g = PatrolGraph.load(graph_path)
    t0 = time.perf_counter()
    p = GlobalPlanner(m)
    build = time.perf_counter() - t0
    d = np.hypot(*(g.pos[:, None] - g.pos[None]).transpose(2, 0, 1))
    a, b = np.unravel_index(np.argmax(d), d.shape)
    times, hits = [], []
    for _ in range(5):
        p._field = None
        p._cache.clear()                            # a goal never seen: Dijkstra over the map
        t0 = time.perf_counter()
        path = p.plan(g.pos[a], g.pos[b])
        times.append(time.perf_counter() - t0)
        p._field = None                             # a goal seen before: from the LRU cache
        t0 = time.perf_counter()
        p.plan(g.pos[a], g.pos[b])
        hits.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    p.plan(g.pos[(a + 1) % g.n], g.pos[b])          # re-plan with the current field
    replan = time.perf_counter() - t0
    # a patrol-like goal (the graph's longest edge) with a robot standing on the path 3 m
    # ahead: the windowed search around it, and for comparison the whole-map search with
    # the same obstacle
    u, v = max(((u, w) for u in range(g.n) for w, _ in g.neighbors[u]),
               key=lambda e: np.hypot(*(g.pos[e[0]] - g.pos[e[1]])))
    p.set_obstacles(np.zeros((0, 2)))
    edge_path = p.plan(g.pos[u], g.pos[v])
    ahead = edge_path[min(len(edge_path) - 2, int(3.0 / p.res))]
    win, full = [], []
    for _ in range(5):
        p.set_obstacles(ahead[None, :])
        t0 = time.perf_counter()
        p.plan(g.pos[u], g.pos[v])
        win.append(time.perf_counter() - t0)
        gi = p._field[0]
        p._graph = None
        t0 = time.perf_counter()
        p._navigation_function(gi, free=False)
        full.append(time.perf_counter() - t0)
        p.clear_obstacles()
    return dict(cells=f"{p.w}x{p.h} @ {p.res:.3f} m", build=build, plan=float(np.median(times)),
                hit=float(np.median(hits)), replan=replan, length=path_length(path),
                pair=(int(a), int(b)), window=float(np.median(win)), full=float(np.median(full)),
                edge=(int(u), int(v), path_length(edge_path)))


# -- live run ---------------------------------------------------------------------------------
def free_port():
    s = socket.socket()
    s.bind(("localhost", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def ros_env():
    out = subprocess.run(["bash", "-c", f"source '{ROOT}/devel/setup.bash' && env -0"],
                         check=True, capture_output=True).stdout
    env = dict(kv.split("=", 1) for kv in out.decode().split("\0") if "=" in kv)
    env["PATH"] = "/usr/bin:/bin:" + env.get("PATH", "")
    return env


def descendants(pid):
    kids = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
                kids.setdefault(ppid, []).append(int(d))
            except (OSError, IndexError, ValueError):
                pass
    out, todo = [], [pid]
    while todo:
        q = todo.pop()
        for c in kids.get(q, []):
            out.append(c)
            todo.append(c)
    return out


def node_of(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            args = f.read().decode(errors="replace").split("\0")
    except OSError:
        return None
    name = next((a.split(":=", 1)[1] for a in args if a.startswith("__name:=")), None)
    if name is None:
        return None
    try:
        with open(f"/proc/{pid}/environ", "rb") as f:
            env = f.read().decode(errors="replace").split("\0")
        ns = next((e.split("=", 1)[1] for e in env if e.startswith("ROS_NAMESPACE=")), "/")
    except OSError:
        ns = "/"
    return ns.strip("/") + "/" + name if ns.strip("/") else name


def live_run(loc, n, duration, env, combined=False):
    yaml_path, graph_path = map_paths("grid")
    g = PatrolGraph.load(graph_path)
    verts = list(range(g.n))
    random.seed(1)
    starts = random.sample(verts, n)
    poses = " ".join(f"{g.pos[v][0]:.3f} {g.pos[v][1]:.3f} 0" for v in starts)
    lines = ['<launch>',
             '  <include file="$(find patrol_stage2d)/launch/stage2d.launch">',
             f'    <arg name="map" value="{yaml_path}"/>',
             f'    <arg name="poses" value="{poses}"/>', '    <arg name="speedup" value="1.0"/>',
             '  </include>',
             '  <node pkg="spqrel_nav_lite" type="map_server" name="map_server" '
             f'args="{yaml_path}"/>']
    for i, v in enumerate(starts):
        lines += ['  <include file="$(find patrolling_sim)/launch/robot.launch">',
                  f'    <arg name="robotname" value="robot_{i}"/>',
                  f'    <arg name="map_yaml" value="{yaml_path}"/>',
                  f'    <arg name="x" value="{g.pos[v][0]:.3f}"/>',
                  f'    <arg name="y" value="{g.pos[v][1]:.3f}"/>',
                  '    <arg name="yaw" value="0"/>',
                  f'    <arg name="localization" value="{loc}"/>',
                  f'    <arg name="combined" value="{str(combined).lower()}"/>', '  </include>']
    lines.append('</launch>')
    tmp = tempfile.mkdtemp(prefix="navbench_")
    launch = os.path.join(tmp, "bench.launch")
    with open(launch, "w") as f:
        f.write("\n".join(lines))
    port = free_port()
    e = dict(env, ROS_MASTER_URI=f"http://localhost:{port}", ROS_HOME=tmp)
    proc = subprocess.Popen(["roslaunch", "-p", str(port), launch], env=e,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    driver = subprocess.Popen(["/usr/bin/python3", __file__, "--drive", str(n),
                               "--duration", str(duration)], env=e, stdout=subprocess.PIPE,
                              text=True, start_new_session=True)
    try:
        time.sleep(10 + 1.5 * n)        # start-up (not measured)
        pids = {}
        for pid in descendants(proc.pid):
            name = node_of(pid)
            if name:
                pids[pid] = name
        t_start = time.monotonic()
        first = {pid: cpu_ticks(pid) for pid in pids}
        time.sleep(duration)
        wall = time.monotonic() - t_start
        last = {pid: cpu_ticks(pid) for pid in pids}
        cpu = {}
        for pid, name in pids.items():
            if first[pid] is not None and last[pid] is not None:
                cpu[name] = 100.0 * (last[pid] - first[pid]) / CLK / wall
        out, _ = driver.communicate(timeout=120)
    finally:
        for p in (driver, proc):
            if p.poll() is None:
                os.killpg(p.pid, 2)
        for p in (driver, proc):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, 9)
    lines = [ln for ln in out.splitlines() if ln.startswith("goals ")]
    return cpu, lines[-1] if lines else "driver printed no result"


def drive(n, duration):
    """Child process: send random patrol-vertex goals to every robot (needs the ROS env)."""
    import actionlib
    import rospy
    from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
    from actionlib_msgs.msg import GoalStatus
    rospy.init_node("nav_bench_driver")
    g = PatrolGraph.load(map_paths("grid")[1])
    clients = [actionlib.SimpleActionClient(f"/robot_{i}/move_base", MoveBaseAction)
               for i in range(n)]
    for c in clients:
        c.wait_for_server(rospy.Duration(60))
    rng = random.Random(2)
    results = {"succeeded": 0, "aborted": 0}
    active = [False] * n

    def send(i):
        v = rng.randrange(g.n)
        goal = MoveBaseGoal()
        goal.target_pose.header.frame_id = "map"
        goal.target_pose.pose.position.x, goal.target_pose.pose.position.y = g.pos[v]
        goal.target_pose.pose.orientation.w = 1.0
        clients[i].send_goal(goal)
        active[i] = True

    t_end = time.monotonic() + duration + 10 + 1.5 * n
    for i in range(n):
        send(i)
    while time.monotonic() < t_end and not rospy.is_shutdown():
        for i, c in enumerate(clients):
            st = c.get_state()
            if active[i] and st in (GoalStatus.SUCCEEDED, GoalStatus.ABORTED):
                results["succeeded" if st == GoalStatus.SUCCEEDED else "aborted"] += 1
                send(i)
        time.sleep(0.2)
    print(f"goals succeeded {results['succeeded']}, aborted {results['aborted']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, default=4)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--skip-live", action="store_true")
    ap.add_argument("--out", default=None)
    ap.add_argument("--drive", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.robots < 1 or a.duration <= 0:
        ap.error("--robots must be >= 1 and --duration > 0")
    if a.drive is not None:
        drive(a.drive, a.duration)
        return
    rows = ["# spqrel_nav_lite benchmark", "",
            f"Machine: {platform.node()}, {os.cpu_count()} CPUs, "
            f"{platform.processor() or platform.machine()}, Python {platform.python_version()}; "
            f"date {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.",
            f"Command: `bench/nav_bench.py --robots {a.robots} --duration {a.duration:.0f}`", "",
            "## Localiser update (predict + 30 beams + estimate + resample)", "",
            "| map | particles | median ms | p95 ms |", "|---|---|---|---|"]
    for name in ("grid", "DIAG_floor1"):
        for n in (100, 500):
            med, p95 = bench_localiser(name, n)
            rows.append(f"| {name} | {n} | {med:.2f} | {p95:.2f} |")
    rows += ["", "## Global planner (longest vertex pair)", "",
             "| map | grid | build s | plan s (new goal: Dijkstra) | plan s (goal seen before: "
             "cache) | re-plan s (current field) | path m | longest edge, robot 3 m ahead: "
             "windowed search s | same, whole-map search s |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name in ("grid", "broughton", "DIAG_floor1"):
        r = bench_planner(name)
        rows.append(f"| {name} | {r['cells']} | {r['build']:.3f} | {r['plan']:.3f} | "
                    f"{r['hit']:.4f} | {r['replan']:.4f} | {r['length']:.1f} (vertices "
                    f"{r['pair'][0]}->{r['pair'][1]}) | {r['window']:.4f} ({r['edge'][0]}->"
                    f"{r['edge'][1]}, {r['edge'][2]:.1f} m) | {r['full']:.3f} |")
    if not a.skip_live:
        env = ros_env()
        rows += ["", f"## Live: grid, {a.robots} robots, patrol_stage2d at 1x, "
                 f"{a.duration:.0f} s wall, random vertex goals", "",
                 "CPU in % of one core, mean over the window (start-up excluded).", "",
                 "| localisation | processes per robot | move_base | localiser | localiser + "
                 "move_base | simulator | goals |",
                 "|---|---|---|---|---|---|---|"]
        for loc in ("fake_localization", "AMCL"):
            for combined in (False, True):
                cpu, out = live_run(loc, a.robots, a.duration, env, combined)
                sim = sum(v for k, v in cpu.items() if "stage2d" in k)
                if combined:
                    nav = [v for k, v in cpu.items() if k.endswith("/robot_nav")]
                    mnav = sum(nav) / max(1, len(nav))
                    rows.append(f"| {loc} | 1 (robot_nav) | - | - | {mnav:.1f} | {sim:.1f} | "
                                f"{out} |")
                else:
                    mb = [v for k, v in cpu.items() if k.endswith("/move_base")]
                    lz = [v for k, v in cpu.items() if k.endswith("/amcl") or
                          k.endswith("/fake_localization")]
                    mmb = sum(mb) / max(1, len(mb))
                    mlz = sum(lz) / max(1, len(lz))
                    rows.append(f"| {loc} | 2 (separate) | {mmb:.1f} | {mlz:.1f} | "
                                f"{mmb + mlz:.1f} | {sim:.1f} | {out} |")
                print(loc, combined, {k: round(v, 1) for k, v in sorted(cpu.items())}, out,
                      flush=True)
    text = "\n".join(rows) + "\n"
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
