#!/usr/bin/python3
"""rostest checker for the interference behaviour (docs/protocol.md section 5),
non-blocking version.

The checker plays robot 0 on /positions: it always claims to stand where robot 1 (an agent)
last said it was. Robot 1 (the higher id) must then report [1,12], cancel its goal, resend
the same goal about 3 s later, and not detect again within 10 s; robot 0's agent-less slot
never reports. The agent keeps answering (its /positions keep flowing during the pause).
"""
import sys
import threading
import time
import unittest

import rospy
import rostest
from move_base_msgs.msg import MoveBaseActionGoal
from nav_msgs.msg import Odometry

import patrol_test_utils as U


class TestInterference(unittest.TestCase):
    def test_interference(self):
        lock = threading.Lock()
        goals, last = [], {}
        pub = rospy.Publisher("/positions", Odometry, queue_size=10)

        def on_pos(msg):
            if msg.header.frame_id == "robot_1/map":
                with lock:
                    last["p"] = msg.pose.pose.position

        def on_goal(msg):
            p = msg.goal.target_pose.pose.position
            with lock:
                goals.append((rospy.get_time(), round(p.x, 3), round(p.y, 3)))

        rospy.Subscriber("/positions", Odometry, on_pos)
        rospy.Subscriber("/robot_1/move_base/goal", MoveBaseActionGoal, on_goal)
        rec = U.ResultsRecorder()
        rec.wait_for(lambda: rec.of_type(10, 1), 60, "announcement of robot 1")
        time.sleep(0.5)
        rec.send(U.GO)
        end = time.time() + 16.0
        while time.time() < end:
            with lock:
                p = last.get("p")
            if p is not None:
                o = Odometry()
                o.header.frame_id = "robot_0/map"
                o.pose.pose.position.x, o.pose.pose.position.y = p.x + 0.5, p.y
                pub.publish(o)
            time.sleep(0.05)
        inter = [t for t, d in rec.of_type(12, 1)]
        self.assertGreaterEqual(len(inter), 1, "no interference reported")
        self.assertEqual(rec.of_type(12, 0), [])
        for a, b in zip(inter, inter[1:]):
            self.assertGreaterEqual(b - a, 9.9, f"detections too close: {inter}")
        # the same goal is resent ~3 s after the first detection
        t0 = inter[0]
        with lock:
            before = [g for g in goals if g[0] <= t0]
            after = [g for g in goals if g[0] > t0]
        self.assertTrue(before and after, goals)
        self.assertEqual(after[0][1:], before[-1][1:], "the interrupted goal was not resent")
        self.assertGreaterEqual(after[0][0] - t0, 2.9)
        self.assertLess(after[0][0] - t0, 8.0)


if __name__ == "__main__":
    rospy.init_node("check_interference")
    rostest.rosrun("patrolling_sim", "check_interference", TestInterference, sys.argv)
