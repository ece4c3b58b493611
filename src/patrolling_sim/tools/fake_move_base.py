#!/usr/bin/python3
"""A stand-in for N robots' move_base, for tests and benchmarks without a simulator (a test
tool: it lives in tools/, outside the library package; node type ``fake_move_base.py``).

One node serves ``robot_i/move_base`` (move_base_msgs/MoveBase action) and
``robot_i/move_base/clear_costmaps`` (std_srvs/Empty) for i = 0..N-1. Each robot is a point
that moves in a straight line toward its goal at ``~speed`` m/s of ROS time, publishes
feedback with ``base_position`` (frame ``map``) at ``~rate`` Hz and succeeds within
``~tolerance`` m of the goal. A new goal preempts the previous one; a cancel stops the robot.

Private parameters:
    ~team_size (int, default: from /initial_pos)   number of robots served
    ~speed (float, 5.0)        m/s
    ~rate (float, 10.0)        Hz of the motion update and feedback
    ~tolerance (float, 0.05)   m
    ~map (str, "")             map name/path; needed only with ~abort_vertices
    ~abort_vertices (list of int, [])  goals at these vertices' positions are aborted
                               after ``~abort_after`` s, the robot not moving meanwhile
                               (the failure path of the agent)
    ~abort_after (float, 0.3)  s
    ~publish_clock (bool, false)  publish /clock itself (for ``/use_sim_time`` true):
                               sim time = wall time since start x ``~time_scale``
    ~time_scale (float, 1.0)   speed-up of the published clock

Start positions come from /initial_pos (flat x0,y0,x1,y1,...).
Counters for tests are set as parameters ``~stats/robot_<i>/{goals,succeeded,aborted,
cancelled,clear_costmaps,cmd_vel}`` once per second.
"""
import math
import sys
import threading
import time

import actionlib

import rospy
from actionlib_msgs.msg import GoalStatus  # noqa: F401  (documentation of states)
from geometry_msgs.msg import Twist
from rosgraph_msgs.msg import Clock
from move_base_msgs.msg import MoveBaseAction, MoveBaseFeedback, MoveBaseResult
from std_srvs.srv import Empty, EmptyResponse

from patrolling_sim.common.errors import PatrolInputError


class FakeRobot:
    def __init__(self, node, i, x, y):
        self.node = node
        self.i = i
        self.x, self.y = float(x), float(y)
        self.gh = None
        self.goal = None
        self.abort_at = None
        self.stats = dict(goals=0, succeeded=0, aborted=0, cancelled=0, clear_costmaps=0,
                          cmd_vel=0)
        ns = f"robot_{i}/move_base"
        self.server = actionlib.ActionServer(ns, MoveBaseAction, self.on_goal, self.on_cancel,
                                             auto_start=False)
        self.srv = rospy.Service(f"{ns}/clear_costmaps", Empty, self.on_clear)
        self.cmd_sub = rospy.Subscriber(f"robot_{i}/cmd_vel", Twist, self.on_cmd_vel,
                                        queue_size=10)

    def start(self):
        self.server.start()

    def on_clear(self, _req):
        with self.node.lock:
            self.stats["clear_costmaps"] += 1
        return EmptyResponse()

    def on_cmd_vel(self, _msg):
        with self.node.lock:
            self.stats["cmd_vel"] += 1

    def on_goal(self, gh):
        with self.node.lock:
            self.stats["goals"] += 1
            if self.gh is not None:
                self.gh.set_canceled(text="preempted by a new goal")
                self.stats["cancelled"] += 1
            p = gh.get_goal().target_pose.pose.position
            gh.set_accepted()
            self.gh = gh
            self.goal = (p.x, p.y)
            self.abort_at = None
            if self.node.is_abort_target(p.x, p.y):
                self.abort_at = rospy.get_time() + self.node.abort_after

    def on_cancel(self, gh):
        with self.node.lock:
            if self.gh is not None and gh == self.gh:
                self.gh.set_canceled()
                self.stats["cancelled"] += 1
                self.gh = None
                self.goal = None

    def step(self, now, dt):
        """Move toward the goal; finish it on arrival or at the abort time."""
        if self.gh is None:
            return
        if self.abort_at is not None:
            # an unreachable goal: the robot does not move, move_base gives up
            if now >= self.abort_at:
                self.gh.set_aborted(text="fake_move_base: vertex configured to abort")
                self.stats["aborted"] += 1
                self.gh = None
                self.goal = None
            return
        gx, gy = self.goal
        dx, dy = gx - self.x, gy - self.y
        d = math.hypot(dx, dy)
        step = self.node.speed * dt
        if d <= max(step, self.node.tolerance):
            self.x, self.y = gx, gy
        else:
            self.x += dx / d * step
            self.y += dy / d * step
        fb = MoveBaseFeedback()
        fb.base_position.header.frame_id = "map"
        fb.base_position.header.stamp = rospy.Time.now()
        fb.base_position.pose.position.x = self.x
        fb.base_position.pose.position.y = self.y
        fb.base_position.pose.orientation.w = 1.0
        self.gh.publish_feedback(fb)
        if math.hypot(gx - self.x, gy - self.y) <= self.node.tolerance:
            self.gh.set_succeeded(MoveBaseResult())
            self.stats["succeeded"] += 1
            self.gh = None
            self.goal = None


class FakeMoveBase:
    def __init__(self):
        flat = rospy.get_param("/initial_pos", None)
        if flat is None:
            raise ValueError("/initial_pos is not set")
        flat = [float(v) for v in flat]
        n = int(rospy.get_param("~team_size", len(flat) // 2))
        if n < 1 or len(flat) < 2 * n:
            raise ValueError(f"~team_size {n} does not fit /initial_pos ({len(flat) // 2} "
                             "positions)")
        self.speed = float(rospy.get_param("~speed", 5.0))
        self.rate = float(rospy.get_param("~rate", 10.0))
        self.tolerance = float(rospy.get_param("~tolerance", 0.05))
        self.abort_after = float(rospy.get_param("~abort_after", 0.3))
        if self.speed <= 0 or self.rate <= 0:
            raise ValueError("~speed and ~rate must be > 0")
        self.abort_xy = []
        abort = list(rospy.get_param("~abort_vertices", []))
        if abort:
            from patrolling_sim.model.graph import PatrolGraph, load_graph
            from patrolling_sim.common.paths import map_files
            _, gpath = map_files(rospy.get_param("~map"))
            g = PatrolGraph(load_graph(gpath))
            self.abort_xy = [tuple(g.pos[int(v)]) for v in abort]
        self.lock = threading.RLock()
        self.robots = [FakeRobot(self, i, flat[2 * i], flat[2 * i + 1]) for i in range(n)]
        for r in self.robots:
            r.start()
        self.last = rospy.get_time()
        self.timer = rospy.Timer(rospy.Duration(1.0 / self.rate), self.tick)
        self.stats_timer = rospy.Timer(rospy.Duration(1.0), self.publish_stats)
        rospy.loginfo("fake_move_base: %d robots, %.2f m/s", n, self.speed)

    def is_abort_target(self, x, y):
        return any(math.hypot(x - ax, y - ay) < 0.01 for ax, ay in self.abort_xy)

    def tick(self, _event):
        now = rospy.get_time()
        with self.lock:
            dt = max(0.0, now - self.last)
            self.last = now
            for r in self.robots:
                r.step(now, dt)

    def publish_stats(self, _event):
        with self.lock:
            snap = {f"robot_{r.i}": dict(r.stats) for r in self.robots}
        rospy.set_param("~stats", snap)


def start_clock(scale, hz=100.0):
    """Publish /clock from a wall-time thread (sim = wall elapsed x scale)."""
    pub = rospy.Publisher("/clock", Clock, queue_size=1)
    t0 = time.time()

    def loop():
        while not rospy.is_shutdown():
            pub.publish(Clock(clock=rospy.Time.from_sec((time.time() - t0) * scale)))
            time.sleep(1.0 / hz)
    threading.Thread(target=loop, daemon=True).start()


def main():
    rospy.init_node("fake_move_base")
    if rospy.get_param("~publish_clock", False):
        scale = float(rospy.get_param("~time_scale", 1.0))
        if scale <= 0:
            sys.stderr.write(f"fake_move_base: error: ~time_scale must be > 0, got {scale}\n")
            return 2
        start_clock(scale)
    try:
        FakeMoveBase()
    except (ValueError, KeyError, PatrolInputError) as e:
        sys.stderr.write(f"fake_move_base: error: {e}\n")
        return 2
    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
