#!/usr/bin/python3
"""Pace of the simulator: /clock against wall time for the configured ~speedup, the reported
real-time factor, periodic snapshots and laser noise."""
import glob
import json
import os
import sys
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String


class Stage2DTimeTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("stage2d_time_test")
        cls.t_start = time.time()
        cls.lock = threading.Lock()
        cls.samples = []  # (wall, sim)
        rospy.Subscriber("/clock", Clock, cls.on_clock, queue_size=1)

    @classmethod
    def on_clock(cls, m):
        with cls.lock:
            cls.samples.append((time.time(), m.clock.to_sec()))

    def measure(self, seconds):
        end = time.time() + 20
        while not self.samples and time.time() < end:
            time.sleep(0.05)
        self.assertTrue(self.samples, "no /clock")
        time.sleep(1.0)  # warm-up
        with self.lock:
            w0, s0 = self.samples[-1]
        time.sleep(seconds)
        with self.lock:
            w1, s1 = self.samples[-1]
        return (s1 - s0) / (w1 - w0)

    def test_pace(self):
        """The pacer never lets sim time run ahead of ~speedup x wall time (beyond one catch-up
        of at most 0.5 wall s after falling behind): an upper bound that load cannot break.
        A loaded machine can only slow the simulator down, so the lower bound is generous
        (a third of the target over 8 s). Exact pace figures: bench/stage2d_bench.py."""
        expected = rospy.get_param("~expected_speedup")
        window = 8.0
        rtf = self.measure(window)
        if expected > 0:
            upper = expected * (1 + 0.6 / window) + 0.2
            self.assertLess(rtf, upper, f"/clock ran at {rtf:.2f}x wall time, above {expected}x")
            self.assertGreater(rtf, expected / 3, f"/clock ran at only {rtf:.2f}x wall time "
                                                  f"(target {expected}x)")
            st = json.loads(rospy.wait_for_message("/stage2d/status", String, 10).data)
            # the status rate is measured over one status period (2 wall s)
            self.assertLess(st["rtf"], expected * (1 + 0.6 / 2.0) + 0.2, msg=str(st))
            self.assertGreater(st["rtf"], 0.0, msg=str(st))
        else:
            # as fast as possible: only a sanity check, not a speed target
            self.assertGreater(rtf, 1.0, f"unthrottled /clock ran at only {rtf:.2f}x wall time")

    def test_periodic_snapshots(self):
        d = rospy.get_param("/stage2d/snapshot_dir", "")
        period = rospy.get_param("/stage2d/snapshot_period", 0.0)
        if not d or period <= 0:
            self.skipTest("no periodic snapshots configured")
        # three periods of sim time
        rospy.sleep(3 * period + 0.1)
        files = [f for f in glob.glob(os.path.join(d, "snapshot_*.png"))
                 if os.path.getmtime(f) >= self.t_start and os.path.getsize(f) > 1000]
        self.assertGreaterEqual(len(files), 3, f"periodic snapshots in {d}: {files}")

    def test_laser_noise(self):
        noise = rospy.get_param("/stage2d/laser_noise", 0.0)
        if noise <= 0:
            self.skipTest("no laser noise configured")
        a = rospy.wait_for_message("/robot_0/base_scan", LaserScan, 20)
        b = rospy.wait_for_message("/robot_0/base_scan", LaserScan, 20)
        while b.header.stamp == a.header.stamp:
            b = rospy.wait_for_message("/robot_0/base_scan", LaserScan, 20)
        ra, rb = np.array(a.ranges), np.array(b.ranges)
        ok = (ra < a.range_max - 1) & (rb < b.range_max - 1)
        diff = (ra - rb)[ok]
        self.assertGreater(len(diff), 500)
        # difference of two independent N(0, s) draws has std s*sqrt(2)
        self.assertAlmostEqual(float(np.std(diff)), noise * np.sqrt(2),
                               delta=0.2 * noise * np.sqrt(2))

    def test_laser_geometry(self):
        """Every 10th beam of robot 0 against an independent brute-force ray march over the
        map image (walls) and the other robots' discs (~check_geometry)."""
        if not rospy.get_param("~check_geometry", False):
            self.skipTest("geometry check not configured")
        import math
        import cv2
        import yaml
        with open(rospy.get_param("/stage2d/map")) as f:
            meta = yaml.safe_load(f)
        img = cv2.imread(os.path.join(os.path.dirname(rospy.get_param("/stage2d/map")),
                                      meta["image"]),
                         cv2.IMREAD_GRAYSCALE)
        occ = ((255.0 - img) / 255.0 > meta["occupied_thresh"])[::-1, :]
        res = meta["resolution"]
        ox, oy = meta["origin"][:2]
        p = [float(v) for v in rospy.get_param("/stage2d/poses").split()]
        robots = [(p[3 * i], p[3 * i + 1], p[3 * i + 2]) for i in range(len(p) // 3)]
        noise = rospy.get_param("/stage2d/laser_noise", 0.0)
        x, y, th = robots[0]
        lx, ly = x + 0.15 * math.cos(th), y + 0.15 * math.sin(th)
        s = rospy.wait_for_message("/robot_0/base_scan", LaserScan, 20)
        bad = []
        n = 0
        for b in range(0, len(s.ranges), 10):
            a = th + s.angle_min + b * s.angle_increment
            c, sn = math.cos(a), math.sin(a)
            exp = s.range_max
            t = 0.0
            while t < s.range_max:
                i = int(math.floor((lx + c * t - ox) / res))
                j = int(math.floor((ly + sn * t - oy) / res))
                if i < 0 or j < 0 or j >= occ.shape[0] or i >= occ.shape[1] or occ[j, i]:
                    exp = t
                    break
                t += 0.004
            for (rx, ry, _) in robots[1:]:
                ex, ey = rx - lx, ry - ly
                tc = ex * c + ey * sn
                d2 = ex * ex + ey * ey - tc * tc
                if tc > 0 and d2 <= 0.225 ** 2:
                    exp = min(exp, tc - math.sqrt(0.225 ** 2 - d2))
            n += 1
            if abs(s.ranges[b] - exp) > res + 4 * noise + 0.005:
                bad.append((b, round(s.ranges[b], 3), round(exp, 3)))
        self.assertGreater(n, 100)
        self.assertEqual(bad, [], f"beams off the map geometry (beam, scan, expected): {bad}")


if __name__ == "__main__":
    rostest.rosrun("patrol_stage2d", "stage2d_time", Stage2DTimeTest, sys.argv)
