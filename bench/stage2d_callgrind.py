#!/usr/bin/python3
"""Load-independent cost of one stage2d_node simulation step: instructions per step, counted
by valgrind's callgrind (the machine's CPU time and real-time factor depend on what else runs;
an instruction count does not).

The node runs headless under callgrind with speedup 0, one scan thread, the command wait and
the cmd_vel watchdog off, every scan computed (~scan_always) and every robot turning on the
spot (one latched cmd_vel, advertised before the node starts). Once the node has logged that
it is set up (map loaded, robots created), 5 s later the counters are zeroed
(callgrind_control --zero), so loading the map and the first connections are left out;
after --seconds more wall seconds the node is stopped with SIGINT and callgrind writes its
counts. Steps are counted by the calls of b2World::Step (in the Box2D library, so never
inlined) divided by the physics sub-steps per step (10 with the default 0.1 s step). The
figure is all instructions of the process after the zeroing divided by the steps: it includes
the ROS threads' background work (a few % at most at this step rate).

  /usr/bin/python3 bench/stage2d_callgrind.py --map cumberland --robots 12
  /usr/bin/python3 bench/stage2d_callgrind.py --binary /other/devel/lib/patrol_stage2d/stage2d_node
"""
import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stage2d_bench import BINARY, ROOT, free_port, ros_env, start_poses  # noqa: E402

SPINNER = r"""
import sys, rospy
from geometry_msgs.msg import Twist
rospy.init_node("bench_spinner", anonymous=True)
t = Twist()
t.angular.z = 0.5
pubs = [rospy.Publisher(f"/robot_{i}/cmd_vel", Twist, queue_size=1, latch=True)
        for i in range(int(sys.argv[1]))]
for p in pubs:
    p.publish(t)
rospy.spin()
"""


def parse_callgrind(path, step_fn):
    """(instructions collected, calls of the function whose name contains step_fn)."""
    names = {}
    total = None
    calls = 0
    pending_cfn = None
    with open(path) as f:
        for line in f:
            if line.startswith(("summary:", "totals:")):
                total = int(line.split()[1])
            m = re.match(r"c?fn=\((\d+)\)(?: (.*))?", line)
            if m:
                if m.group(2):
                    names[m.group(1)] = m.group(2).strip()
                pending_cfn = names.get(m.group(1), "") if line.startswith("cfn=") else None
                continue
            if line.startswith("calls=") and pending_cfn is not None:
                if step_fn in pending_cfn:
                    calls += int(line[6:].split()[0])
                pending_cfn = None
    return total, calls


def wait_for_publishers(env, n, timeout=60.0):
    """Until the spinner advertises every robot's cmd_vel."""
    code = ("import rosgraph, sys; m = rosgraph.Master('/cg'); "
            "pubs = [t for t, _ in m.getSystemState()[0]]; "
            f"sys.exit(0 if all(f'/robot_{{i}}/cmd_vel' in pubs for i in range({n})) else 1)")
    deadline = time.time() + timeout
    while subprocess.run(["/usr/bin/python3", "-c", code], env=env).returncode != 0:
        if time.time() > deadline:
            sys.exit("stage2d_callgrind: error: the cmd_vel publisher did not start")
        time.sleep(0.5)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--binary", default=BINARY)
    ap.add_argument("--map", default="cumberland")
    ap.add_argument("--robots", type=int, default=12)
    ap.add_argument("--seconds", type=float, default=60.0, help="wall seconds under callgrind")
    ap.add_argument("--substeps", type=int, default=10, help="physics sub-steps per step")
    a = ap.parse_args()
    if not os.access(a.binary, os.X_OK):
        sys.exit(f"stage2d_callgrind: error: {a.binary} missing: run 'make build' first")
    env = ros_env()
    port = free_port()
    env["ROS_MASTER_URI"] = f"http://127.0.0.1:{port}"
    out = os.path.join(tempfile.mkdtemp(prefix="stage2d_cg_"), "callgrind.out")
    yaml_path = os.path.join(ROOT, "maps", a.map, f"{a.map}.yaml")
    procs = []
    try:
        procs.append(subprocess.Popen(["/usr/bin/rosmaster", "--core", "-p", str(port)], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      start_new_session=True))
        time.sleep(2)
        # the latched command is there before the node subscribes: every robot turns from
        # its first steps, so every counted step recomputes every scan
        procs.append(subprocess.Popen(["/usr/bin/python3", "-c", SPINNER, str(a.robots)], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      start_new_session=True))
        wait_for_publishers(env, a.robots)
        # --fair-sched=yes: with valgrind's default (unfair) thread scheduling the busy main
        # thread starved roscpp's other threads, so the node never acted on the SIGINT below
        # and was killed before callgrind wrote its counts (valgrind 3.19)
        node = subprocess.Popen(
            ["stdbuf", "-oL", "valgrind", "--tool=callgrind", "--fair-sched=yes",
             f"--callgrind-out-file={out}",
             a.binary, "__name:=stage2d", f"_map:={yaml_path}",
             f"_poses:={start_poses(a.map, a.robots)}", "_speedup:=0", "_cmd_vel_timeout:=1e9",
             "_sync_timeout:=0", "_threads:=1", "_scan_always:=true"],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, start_new_session=True,
            text=True)
        procs.append(node)
        for line in node.stdout:  # wait until set up
            if "robots, step" in line:
                break
        else:
            sys.exit("stage2d_callgrind: error: the node exited during set-up")
        threading.Thread(target=lambda: [None for _ in node.stdout], daemon=True).start()
        time.sleep(5.0)  # connections up, robots turning
        subprocess.run(["callgrind_control", "--zero", str(node.pid)], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(a.seconds)
        os.killpg(node.pid, signal.SIGINT)
        node.wait(120)
    finally:
        for p in reversed(procs):
            try:
                os.killpg(p.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
        for p in procs:
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
    total, calls = parse_callgrind(out, "b2World::Step")
    steps = calls / a.substeps
    if not total or not steps:
        sys.exit(f"stage2d_callgrind: error: {out}: no instructions or no calls of b2World::Step")
    print(f"| {a.map} | {a.robots} | {steps:.0f} | {total:,} | {total / steps:,.0f} |")


if __name__ == "__main__":
    main()
