#!/usr/bin/python3
"""Benchmark of patrol_stage2d/stage2d_node: unthrottled real-time factor (speedup 0), CPU and
memory, for several maps and team sizes, in three laser modes:

  none  no scan computed (nobody subscribes)
  calc  every robot's scan computed at 10 Hz sim time (~scan_always), not sent
  sub   every robot's scan computed and sent to a subscriber process (rospy, AnyMsg: no
        deserialisation) -- the subscriber's CPU is reported separately

Each run: own rosmaster on a free port, node started with the map and computed start
positions (scripts/graph_tool.py startposes); by default every robot turns on the spot (one
latched cmd_vel, watchdog off), so every scan is recomputed; warm-up, then a measuring
window. The RTF is sim seconds per wall second over the window (from the node's periodic log
lines); CPU% is the node's user+system time over the window (100 % = one core); "sim s per
node CPU s" = RTF / (CPU% / 100), a figure less sensitive to other load on the machine; RSS
is the node's resident memory.

  /usr/bin/python3 bench/stage2d_bench.py                       # default matrix, markdown table
  /usr/bin/python3 bench/stage2d_bench.py --maps cumberland --robots 12 200 --modes calc
"""
import argparse
import os
import platform
import re
import signal
import socket
import subprocess
import sys
import threading
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
BINARY = os.path.join(ROOT, "devel", "lib", "patrol_stage2d", "stage2d_node")
TICK = os.sysconf("SC_CLK_TCK")

SPINNER = r"""
import sys, rospy
from geometry_msgs.msg import Twist
rospy.init_node("bench_spinner", anonymous=True)
n = int(sys.argv[1])
t = Twist()
t.angular.z = 0.5
pubs = [rospy.Publisher(f"/robot_{i}/cmd_vel", Twist, queue_size=1, latch=True) for i in range(n)]
for p in pubs:
    p.publish(t)
rospy.spin()
"""

SUBSCRIBER = r"""
import sys, rospy
rospy.init_node("bench_scan_sub", anonymous=True)
n = int(sys.argv[1])
count = [0]
def cb(m): count[0] += 1
subs = [rospy.Subscriber(f"/robot_{i}/base_scan", rospy.AnyMsg, cb, queue_size=1) for i in range(n)]
rospy.spin()
"""


def ros_env():
    setup = os.path.join(ROOT, "devel", "setup.bash")
    if not os.path.isfile(setup):
        sys.exit(f"stage2d_bench: error: {setup} missing: run 'make build' first")
    out = subprocess.run(["bash", "-c", f"source '{setup}' && env -0"], check=True,
                         capture_output=True).stdout
    env = dict(kv.split("=", 1) for kv in out.decode().split("\0") if "=" in kv)
    env["PATH"] = "/usr/bin:/bin:" + env.get("PATH", "")
    return env


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_poses(map_name, n):
    out = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "graph_tool.py"),
                          "startposes", map_name, str(n)], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr.strip() or out.stdout.strip())
    vals = []
    for line in out.stdout.splitlines():
        if line.startswith("robot_"):
            f = line.split()
            vals += [f[1], f[2], "1.5708"]
    if len(vals) != 3 * n:
        raise RuntimeError(f"graph_tool gave {len(vals) // 3} poses for {n} robots")
    return " ".join(vals)


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


LOG_RE = re.compile(r"\[ INFO\] \[(\d+\.\d+)\]: stage2d: sim time ([0-9.]+) s, real-time factor")


def read_log(stream, out):
    """Collects (wall, sim) pairs from the node's periodic real-time-factor log lines."""
    for line in stream:
        m = LOG_RE.search(line)
        if m:
            out.append((float(m.group(1)), float(m.group(2))))


def run_one(base_env, map_name, n, mode, warmup, window, motion, binary=BINARY):
    port = free_port()
    env = dict(base_env, ROS_MASTER_URI=f"http://127.0.0.1:{port}")
    procs = []

    def spawn(args, stdout=subprocess.DEVNULL):
        p = subprocess.Popen(args, env=env, stdout=stdout, stderr=subprocess.DEVNULL,
                             start_new_session=True, text=True)
        procs.append(p)
        return p

    try:
        spawn(["/usr/bin/rosmaster", "--core", "-p", str(port)])
        deadline = time.time() + 20
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                break
            except OSError:
                if time.time() > deadline:
                    raise RuntimeError("rosmaster did not start")
                time.sleep(0.1)
        yaml_path = os.path.join(ROOT, "maps", map_name, f"{map_name}.yaml")
        poses = start_poses(map_name, n)
        node = spawn(["stdbuf", "-oL", binary, "__name:=stage2d", f"_map:={yaml_path}",
                      f"_poses:={poses}", "_speedup:=0", "_log_period:=0.5",
                      "_cmd_vel_timeout:=1e9",
                      f"_scan_always:={'true' if mode == 'calc' else 'false'}"],
                     stdout=subprocess.PIPE)
        samples = []
        threading.Thread(target=read_log, args=(node.stdout, samples), daemon=True).start()
        if motion == "spin":
            # every robot turns on the spot (one latched command), so no scan can be reused
            spawn(["/usr/bin/python3", "-c", SPINNER, str(n)])
        sub = None
        if mode == "sub":
            sub = spawn(["/usr/bin/python3", "-c", SUBSCRIBER, str(n)])
        time.sleep(warmup)
        if node.poll() is not None:
            raise RuntimeError(f"node exited {node.returncode}")
        w_start = time.time()
        c0 = cpu_seconds(node.pid)
        cs0 = cpu_seconds(sub.pid) if sub else 0.0
        time.sleep(window)
        w_end = time.time()
        c1 = cpu_seconds(node.pid)
        cs1 = cpu_seconds(sub.pid) if sub else 0.0
        rss = rss_mb(node.pid)
        inside = [(w, t) for w, t in list(samples) if w_start - 0.6 <= w <= w_end + 0.1]
        if len(inside) < 2:
            raise RuntimeError(f"only {len(inside)} real-time-factor log lines in the window")
        (w0, s0), (w1, s1) = inside[0], inside[-1]
        return {
            "map": map_name, "robots": n, "mode": mode,
            "rtf": (s1 - s0) / (w1 - w0),
            "sim_per_cpu": (s1 - s0) / (w1 - w0) / max(1e-9, (c1 - c0) / (w_end - w_start)),
            "cpu": 100.0 * (c1 - c0) / (w_end - w_start),
            "sub_cpu": 100.0 * (cs1 - cs0) / (w_end - w_start) if sub else None,
            "rss": rss,
            "load": os.getloadavg()[0],
        }
    finally:
        for p in reversed(procs):
            try:
                os.killpg(p.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
        for p in reversed(procs):
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--maps", nargs="+", default=["grid", "cumberland"])
    ap.add_argument("--robots", nargs="+", type=int, default=[1, 4, 8, 12, 32, 100, 200])
    ap.add_argument("--modes", nargs="+", default=["none", "calc", "sub"],
                    choices=["none", "calc", "sub"])
    ap.add_argument("--sub-max-robots", type=int, default=32,
                    help="run the 'sub' mode only up to this many robots (rospy subscriber cost)")
    ap.add_argument("--motion", choices=["spin", "still"], default="spin",
                    help="spin: every robot turns on the spot (default); still: robots stand "
                         "(a standing robot reuses its wall ranges)")
    ap.add_argument("--warmup", type=float, default=3.0)
    ap.add_argument("--window", type=float, default=5.0)
    ap.add_argument("--binary", default=BINARY,
                    help="stage2d_node to measure (default: this workspace's build)")
    args = ap.parse_args()
    # SIGTERM -> SystemExit, so the finally blocks stop this run's master and node
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if not os.access(args.binary, os.X_OK):
        sys.exit(f"stage2d_bench: error: --binary: {args.binary} missing: run 'make build' first")
    for n in args.robots:
        if n < 1:
            sys.exit(f"stage2d_bench: error: --robots: {n} is not >= 1")
    env = ros_env()
    print(f"<!-- {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.node()}, "
          f"{os.cpu_count()} cores, {platform.processor() or platform.machine()}, "
          f"robots {args.motion} -->")
    print("| map | robots | lasers | RTF (speedup 0) | sim s per node CPU s | node CPU % "
          "| node RSS MB | subscriber CPU % | load avg |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for m in args.maps:
        for n in args.robots:
            for mode in args.modes:
                if mode == "sub" and n > args.sub_max_robots:
                    continue
                try:
                    r = run_one(env, m, n, mode, args.warmup, args.window, args.motion, args.binary)
                except (RuntimeError, subprocess.TimeoutExpired) as e:
                    print(f"| {m} | {n} | {mode} | error: {str(e)[:80]} | | | | | |", flush=True)
                    continue
                sub = f"{r['sub_cpu']:.0f}" if r["sub_cpu"] is not None else ""
                print(f"| {m} | {n} | {mode} | {r['rtf']:.1f} | {r['sim_per_cpu']:.1f} "
                      f"| {r['cpu']:.0f} | {r['rss']:.0f} | {sub} | {r['load']:.1f} |",
                      flush=True)


if __name__ == "__main__":
    main()
