#!/usr/bin/python3
"""Integration test of stage2d_node with 3 robots on the grid map: topics, frames, driving,
watchdog, walls, robot-robot contacts, laser geometry, reset/set_pose and snapshots."""
import glob
import json
import math
import os
import sys
import threading
import time
import unittest

import cv2
import numpy as np
import rospy
import rostest
import yaml
from geometry_msgs.msg import Pose2D, Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from patrol_stage2d.srv import SetPose

N = 3
RADIUS = 0.225
LASER_X = 0.15


def yaw_of(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


class GridGeometry:
    """Independent reference: the map image, ray-marched in tiny steps."""

    def __init__(self, yaml_path):
        with open(yaml_path) as f:
            meta = yaml.safe_load(f)
        img = cv2.imread(os.path.join(os.path.dirname(yaml_path), meta["image"]),
                         cv2.IMREAD_GRAYSCALE)
        occ = (255.0 - img) / 255.0 > meta["occupied_thresh"]
        self.occ = occ[::-1, :]  # row 0 = bottom
        self.res = meta["resolution"]
        self.ox, self.oy = meta["origin"][:2]

    def occupied(self, x, y):
        i = int(math.floor((x - self.ox) / self.res))
        j = int(math.floor((y - self.oy) / self.res))
        if i < 0 or j < 0 or j >= self.occ.shape[0] or i >= self.occ.shape[1]:
            return True
        return bool(self.occ[j, i])

    def ray(self, x, y, a, max_range=20.0, step=0.002):
        c, s = math.cos(a), math.sin(a)
        t = 0.0
        while t < max_range:
            if self.occupied(x + c * t, y + s * t):
                return t
            t += step
        return max_range


class Latest:
    """Keeps the latest message of a topic and a history."""

    def __init__(self, topic, cls, keep=False):
        self.msg = None
        self.history = []
        self.keep = keep
        self.lock = threading.Lock()
        self.sub = rospy.Subscriber(topic, cls, self.cb, queue_size=50)

    def cb(self, m):
        with self.lock:
            self.msg = m
            if self.keep:
                self.history.append(m)

    def wait(self, timeout=10.0, cond=lambda m: True):
        end = time.time() + timeout
        while time.time() < end and not rospy.is_shutdown():
            with self.lock:
                if self.msg is not None and cond(self.msg):
                    return self.msg
            time.sleep(0.01)
        return None


class Stage2DSimTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("stage2d_sim_test")
        cls.geo = GridGeometry(rospy.get_param("/stage2d/map"))
        cls.gt = [Latest(f"/robot_{i}/base_pose_ground_truth", Odometry, keep=True)
                  for i in range(N)]
        cls.odom = [Latest(f"/robot_{i}/odom", Odometry) for i in range(N)]
        cls.scan = [Latest(f"/robot_{i}/base_scan", LaserScan) for i in range(N)]
        cls.status = Latest("/stage2d/status", String)
        cls.cmd = [rospy.Publisher(f"/robot_{i}/cmd_vel", Twist, queue_size=10) for i in range(N)]
        rospy.wait_for_service("/stage2d/reset", 20)
        cls.reset = rospy.ServiceProxy("/stage2d/reset", Empty)
        cls.snapshot = rospy.ServiceProxy("/stage2d/snapshot", Empty)
        cls.set_pose = []
        for i in range(N):
            rospy.wait_for_service(f"/robot_{i}/set_pose", 20)
            cls.set_pose.append(rospy.ServiceProxy(f"/robot_{i}/set_pose", SetPose))
        for g in cls.gt:
            assert g.wait(20) is not None, "no ground truth"

    # ---------------------------------------------------------------- helpers
    def sim_now(self):
        return rospy.Time.now().to_sec()

    def sim_sleep(self, dt):
        rospy.sleep(dt)

    def teleport(self, i, x, y, th):
        r = self.set_pose[i](Pose2D(x, y, th))
        self.assertTrue(r.success, r.message)

    def fresh_gt(self, i):
        """Ground truth stamped after now (the teleport has been applied)."""
        t = self.sim_now()
        m = self.gt[i].wait(10, lambda m: m.header.stamp.to_sec() > t + 0.06)
        self.assertIsNotNone(m, f"no fresh ground truth of robot {i}")
        return m

    def drive(self, cmds, duration, stop=True):
        """Publishes {robot: (v, w)} every 0.05 s of sim time for `duration` sim seconds."""
        t_end = self.sim_now() + duration
        while self.sim_now() < t_end and not rospy.is_shutdown():
            for i, (v, w) in cmds.items():
                t = Twist()
                t.linear.x, t.angular.z = v, w
                self.cmd[i].publish(t)
            self.sim_sleep(0.05)
        if stop:
            for i in cmds:
                self.cmd[i].publish(Twist())

    def status_json(self, timeout=10):
        t0 = self.sim_now()
        m = self.status.wait(timeout, lambda m: json.loads(m.data)["sim_time"] > t0)
        self.assertIsNotNone(m, "no status")
        return json.loads(m.data)

    def park_all(self):
        """Known, separated poses for all robots (ids 0..2 along the top corridor)."""
        self.reset()
        for i in range(N):
            self.cmd[i].publish(Twist())
        self.teleport(0, 1.425, 12.825, math.pi / 2)
        self.teleport(1, 12.825, 1.425, 0.0)
        self.teleport(2, 24.225, 12.825, -math.pi / 2)
        for i in range(N):
            self.fresh_gt(i)

    # ---------------------------------------------------------------- tests
    def test_01_topics_and_frames(self):
        for i in range(N):
            o = self.odom[i].wait(10)
            self.assertIsNotNone(o, f"robot_{i}/odom missing")
            self.assertEqual(o.header.frame_id, f"robot_{i}/odom")
            self.assertEqual(o.child_frame_id, f"robot_{i}/base_link")
            g = self.gt[i].wait(10)
            self.assertEqual(g.header.frame_id, "map")
            self.assertEqual(g.child_frame_id, f"robot_{i}/base_link")
            s = self.scan[i].wait(10)
            self.assertIsNotNone(s, f"robot_{i}/base_scan missing")
            self.assertEqual(s.header.frame_id, f"robot_{i}/base_laser_link")
            self.assertEqual(len(s.ranges), 1081)
            self.assertAlmostEqual(s.angle_min, -math.radians(135), places=4)
            self.assertAlmostEqual(s.angle_max, math.radians(135), places=4)
            self.assertAlmostEqual(s.range_max, 20.0, places=4)
        # /clock advances
        c = rospy.wait_for_message("/clock", Clock, 10)
        self.assertGreater(c.clock.to_sec(), 0)
        # tf: all 2N transforms, no leading slashes, in one message per step
        msg = rospy.wait_for_message("/tf", TFMessage, 10)
        pairs = {(t.header.frame_id, t.child_frame_id) for t in msg.transforms}
        for i in range(N):
            self.assertIn((f"robot_{i}/odom", f"robot_{i}/base_link"), pairs)
            self.assertIn((f"robot_{i}/base_link", f"robot_{i}/base_laser_link"), pairs)
        for t in msg.transforms:
            self.assertFalse(t.header.frame_id.startswith("/") or t.child_frame_id.startswith("/"))
            if t.child_frame_id.endswith("base_laser_link"):
                self.assertAlmostEqual(t.transform.translation.x, LASER_X, places=6)
        # topic types as seen by the master
        types = dict(rospy.get_published_topics())
        for i in range(N):
            self.assertEqual(types[f"/robot_{i}/odom"], "nav_msgs/Odometry")
            self.assertEqual(types[f"/robot_{i}/base_pose_ground_truth"], "nav_msgs/Odometry")
            self.assertEqual(types[f"/robot_{i}/base_scan"], "sensor_msgs/LaserScan")
        self.assertEqual(types["/clock"], "rosgraph_msgs/Clock")
        self.assertEqual(types["/tf"], "tf2_msgs/TFMessage")

    def test_02_drive_distance_and_odometry(self):
        self.park_all()
        self.teleport(1, 4.0, 1.425, 0.0)  # bottom corridor, heading east, clear for > 15 m
        g0 = self.fresh_gt(1)
        o0 = self.odom[1].wait(5)
        self.drive({1: (0.5, 0.0)}, 4.0)
        self.sim_sleep(1.0)
        g1 = self.fresh_gt(1)
        o1 = self.odom[1].wait(5, lambda m: m.header.stamp >= g1.header.stamp)
        d_gt = math.hypot(g1.pose.pose.position.x - g0.pose.pose.position.x,
                          g1.pose.pose.position.y - g0.pose.pose.position.y)
        self.assertAlmostEqual(d_gt, 2.0, delta=0.1, msg=f"drove {d_gt:.3f} m instead of 2 m")
        self.assertAlmostEqual(g1.pose.pose.position.y, 1.425, delta=0.01)
        d_odom = math.hypot(o1.pose.pose.position.x - o0.pose.pose.position.x,
                            o1.pose.pose.position.y - o0.pose.pose.position.y)
        # Stage model: constant relative error of at most odom_error x = 1 %
        self.assertLessEqual(abs(d_odom - d_gt), 0.01 * d_gt + 0.005,
                             f"odometry {d_odom:.4f} m vs ground truth {d_gt:.4f} m")

    def test_03_watchdog_stops(self):
        self.park_all()
        self.teleport(1, 4.0, 1.425, 0.0)
        g0 = self.fresh_gt(1)
        self.drive({1: (0.5, 0.0)}, 1.0, stop=False)  # no explicit stop: the watchdog must act
        t_last = self.sim_now()
        self.sim_sleep(1.5)
        ga = self.fresh_gt(1)
        self.sim_sleep(1.0)
        gb = self.fresh_gt(1)
        moved_after = abs(gb.pose.pose.position.x - ga.pose.pose.position.x)
        self.assertLess(moved_after, 1e-3, "robot still moving after the cmd_vel watchdog")
        coast = ga.pose.pose.position.x - g0.pose.pose.position.x - 0.5 * 1.0
        # it keeps the last command for at most 0.5 s (+ deceleration and latency)
        self.assertLess(coast, 0.5 * 0.5 + 0.1, f"coasted {coast:.3f} m after the last cmd_vel")
        self.assertGreater(coast, 0.5 * 0.5 - 0.15, f"stopped too early ({coast:.3f} m)")
        del t_last

    def test_04_wall_stops_robot(self):
        self.park_all()
        x, y = 1.425, 23.0
        wall = self.geo.ray(x, y, math.pi / 2)  # distance from the centre to the top wall
        self.teleport(0, x, y, math.pi / 2)
        self.fresh_gt(0)
        before = self.status_json()["contacts"][0]["wall"]
        self.gt[0].history.clear()
        self.drive({0: (1.0, 0.0)}, wall / 1.0 + 2.0)
        self.sim_sleep(0.5)
        g = self.fresh_gt(0)
        top = y + wall
        for m in self.gt[0].history:  # never inside the wall
            self.assertLessEqual(m.pose.pose.position.y + RADIUS, top + 0.01)
        gap = top - (g.pose.pose.position.y + RADIUS)
        self.assertGreaterEqual(gap, -0.01, "robot penetrated the wall")
        self.assertLessEqual(gap, 0.05, f"robot stopped {gap:.3f} m before the wall")
        self.assertAlmostEqual(g.pose.pose.position.x, x, delta=0.02)
        after = self.status_json()["contacts"][0]["wall"]
        self.assertGreater(after, before, "wall contact not counted")

    def test_05_robots_do_not_overlap(self):
        self.park_all()
        self.teleport(1, 10.0, 1.425, 0.0)
        self.teleport(2, 12.0, 1.425, math.pi)
        self.fresh_gt(1)
        self.fresh_gt(2)
        before = self.status_json()["robot_contacts"]
        for h in self.gt:
            h.history.clear()
        self.drive({1: (0.5, 0.0), 2: (0.5, 0.0)}, 4.0)
        self.sim_sleep(0.3)
        a, b = self.fresh_gt(1), self.fresh_gt(2)
        d = math.hypot(a.pose.pose.position.x - b.pose.pose.position.x,
                       a.pose.pose.position.y - b.pose.pose.position.y)
        self.assertGreaterEqual(d, 2 * RADIUS - 0.02, f"robots overlap: centres {d:.3f} m apart")
        self.assertLessEqual(d, 2 * RADIUS + 0.05, "robots did not meet")
        # never overlapping at any ground truth stamp
        h1 = {m.header.stamp: m for m in self.gt[1].history}
        for m in self.gt[2].history:
            o = h1.get(m.header.stamp)
            if o is not None:
                dd = math.hypot(o.pose.pose.position.x - m.pose.pose.position.x,
                                o.pose.pose.position.y - m.pose.pose.position.y)
                self.assertGreaterEqual(dd, 2 * RADIUS - 0.02)
        self.assertGreater(self.status_json()["robot_contacts"], before,
                           "robot contact not counted")

    def test_06_laser_matches_walls(self):
        self.park_all()
        x, y, th = 1.425, 20.0, math.pi / 2
        self.teleport(0, x, y, th)
        g = self.fresh_gt(0)
        t = g.header.stamp
        s = self.scan[0].wait(10, lambda m: m.header.stamp > t)
        self.assertIsNotNone(s)
        lx, ly = x + LASER_X * math.cos(th), y + LASER_X * math.sin(th)
        checked = 0
        for b in range(0, len(s.ranges), 45):
            a = th + s.angle_min + b * s.angle_increment
            exp = self.geo.ray(lx, ly, a)
            self.assertAlmostEqual(s.ranges[b], exp, delta=self.geo.res,
                                   msg=f"beam {b}: {s.ranges[b]:.3f} m, map says {exp:.3f} m")
            checked += 1
        self.assertGreater(checked, 20)

    def test_07_robots_in_scans(self):
        self.park_all()
        # robot 1 looks north along the left corridor at robot 0, 4 m ahead
        self.teleport(0, 1.425, 20.0, 0.0)
        self.teleport(1, 1.425, 16.0, math.pi / 2)
        g = self.fresh_gt(1)
        self.fresh_gt(0)
        t = g.header.stamp
        s = self.scan[1].wait(10, lambda m: m.header.stamp > t)
        mid = int(round((0.0 - s.angle_min) / s.angle_increment))
        exp = 4.0 - LASER_X - RADIUS
        self.assertAlmostEqual(s.ranges[mid], exp, delta=0.01)
        wall = self.geo.ray(1.425, 16.0 + LASER_X, math.pi / 2)
        self.assertGreater(wall, exp + 1.0)  # the hit is the robot, not the wall
        # robot 0 (facing east) sees robot 1 on its right side (-90 deg)
        s0 = self.scan[0].wait(10, lambda m: m.header.stamp > t)
        b = int(round((-math.pi / 2 - s0.angle_min) / s0.angle_increment))
        exp0 = math.hypot(1.425 - (1.425 + LASER_X), 20.0 - 16.0) - RADIUS
        self.assertAlmostEqual(min(s0.ranges[b - 5:b + 6]), exp0, delta=0.03)

    def test_08_set_pose_and_reset(self):
        self.park_all()
        self.teleport(2, 18.525, 7.125, 1.0)
        g = self.fresh_gt(2)
        self.assertAlmostEqual(g.pose.pose.position.x, 18.525, delta=1e-3)
        self.assertAlmostEqual(g.pose.pose.position.y, 7.125, delta=1e-3)
        self.assertAlmostEqual(yaw_of(g.pose.pose.orientation), 1.0, delta=1e-3)
        # inside a wall block and off the map: refused
        r = self.set_pose[2](Pose2D(4.3, 4.3, 0.0))
        self.assertFalse(r.success)
        self.assertIn("wall", r.message)
        r = self.set_pose[2](Pose2D(-5.0, 4.3, 0.0))
        self.assertFalse(r.success)
        self.assertIn("off the map", r.message)
        self.reset()
        starts = rospy.get_param("/stage2d/poses").split()
        for i in range(N):
            g = self.fresh_gt(i)
            self.assertAlmostEqual(g.pose.pose.position.x, float(starts[3 * i]), delta=1e-3)
            self.assertAlmostEqual(g.pose.pose.position.y, float(starts[3 * i + 1]), delta=1e-3)
            self.assertAlmostEqual(yaw_of(g.pose.pose.orientation), float(starts[3 * i + 2]),
                                   delta=1e-3)

    def test_09_snapshot(self):
        d = rospy.get_param("/stage2d/snapshot_dir")
        t0 = time.time() - 0.01
        self.snapshot()
        new = [f for f in glob.glob(os.path.join(d, "snapshot_*.png")) if os.path.getmtime(f) >= t0]
        self.assertEqual(len(new), 1, f"expected one new snapshot in {d}")
        self.assertGreater(os.path.getsize(new[0]), 1000)
        with open(new[0], "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        img = cv2.imread(new[0])
        self.assertIsNotNone(img)
        self.assertGreater(img.shape[0], 300)
        # robots are drawn in colour on a grey map
        self.assertTrue((np.abs(img[:, :, 0].astype(int) - img[:, :, 2]) > 100).any())


if __name__ == "__main__":
    rostest.rosrun("patrol_stage2d", "stage2d_sim", Stage2DSimTest, sys.argv)
