#!/usr/bin/python3
"""rostest client: sends move_base goals to robot_0 one after the other and checks outcomes.

~goals: "x y EXPECT; x y EXPECT; ..." with EXPECT S (succeeded), A (aborted with a reason) or
SA (either, e.g. goal behind a temporary obstacle). ~map: yaml (to compute the shortest path
length); ~time_factor: a SUCCEEDED goal must take <= time_factor x shortest-path length at
max speed 1 m/s (0 = no check; only for S goals); ~max_contacts (-1 = no check): robot
contacts counted by the simulator (/contacts of the kinematic test sim, or wall + robot
contacts from /stage2d/status);
~simple_goal "x y": finally published on move_base_simple/goal, the robot must get there.
"""
import math
import sys
import unittest

import actionlib
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path
from std_msgs.msg import Int32, String
from std_srvs.srv import Empty

from spqrel_nav_lite.mapio import load_map
from spqrel_nav_lite.planner import GlobalPlanner, path_length

# xy_goal_tolerance 0.4 m, plus the motion the robot makes after move_base sees it inside the
# tolerance: one simulator step (0.1 s) at up to 1 m/s before the stop takes effect, then
# braking. Ground truth is read once the robot has come to rest.
REACHED = 0.4 + 0.1


class NavGoals(unittest.TestCase):
    def test_goals(self):
        ns = rospy.get_param("~robot", "robot_0")
        spec = rospy.get_param("~goals")
        goals = []
        for part in spec.split(";"):
            if part.strip():
                x, y, e = part.split()
                goals.append((float(x), float(y), e))
        factor = float(rospy.get_param("~time_factor", 0.0))
        max_contacts = int(rospy.get_param("~max_contacts", -1))
        planner = GlobalPlanner(load_map(rospy.get_param("~map")))
        self.truth = None
        self.contacts = 0
        self.plans = 0
        rospy.Subscriber(f"/{ns}/base_pose_ground_truth", Odometry, self.on_truth)
        rospy.Subscriber("/contacts", Int32, self.on_contacts)
        rospy.Subscriber("/stage2d/status", String, self.on_status)
        rospy.Subscriber(f"/{ns}/move_base/plan", Path, self.on_plan)
        client = actionlib.SimpleActionClient(f"/{ns}/move_base", MoveBaseAction)
        self.assertTrue(client.wait_for_server(rospy.Duration(60)), "no move_base server")
        rospy.wait_for_service(f"/{ns}/move_base/clear_costmaps", 30)
        rospy.ServiceProxy(f"/{ns}/move_base/clear_costmaps", Empty)()
        while self.truth is None and not rospy.is_shutdown():
            rospy.sleep(0.1)
        report = []
        for gx, gy, expect in goals:
            start = self.truth
            try:
                shortest = path_length(planner.plan(start[:2], (gx, gy)))
            except Exception:
                shortest = math.nan
            g = MoveBaseGoal()
            g.target_pose.header.frame_id = "map"
            g.target_pose.header.stamp = rospy.Time.now()
            g.target_pose.pose.position.x, g.target_pose.pose.position.y = gx, gy
            g.target_pose.pose.orientation.w = 1.0
            t0 = rospy.get_time()
            client.send_goal(g)
            finished = client.wait_for_result(rospy.Duration(400))
            dt = rospy.get_time() - t0
            state = client.get_state()
            text = client.get_goal_status_text()
            rospy.sleep(0.5)                    # let the robot come to rest
            end = self.truth
            err = math.hypot(end[0] - gx, end[1] - gy)
            line = (f"goal ({gx:.2f},{gy:.2f}) expect {expect}: state {state} '{text}' "
                    f"in {dt:.1f} s, shortest {shortest:.1f} m, final error {err:.2f} m")
            rospy.loginfo(line)
            report.append(line)
            self.assertTrue(finished, line + ": no result")
            if expect == "S":
                self.assertEqual(state, GoalStatus.SUCCEEDED, line)
            elif expect == "A":
                self.assertEqual(state, GoalStatus.ABORTED, line)
                self.assertTrue(len(text) > 5, line + ": no reason")
            else:
                self.assertIn(state, (GoalStatus.SUCCEEDED, GoalStatus.ABORTED), line)
                if state == GoalStatus.ABORTED:
                    self.assertTrue(len(text) > 5, line + ": no reason")
            if state == GoalStatus.SUCCEEDED:
                self.assertLess(err, REACHED, line)
                if factor > 0 and expect == "S" and math.isfinite(shortest):
                    self.assertLessEqual(dt, factor * shortest / 1.0 + 2.0, line)
        simple = rospy.get_param("~simple_goal", "")
        if simple:      # the move_base_simple/goal topic drives the robot too
            sx, sy = (float(v) for v in simple.split())
            pub = rospy.Publisher(f"/{ns}/move_base_simple/goal", PoseStamped, queue_size=1,
                                  latch=True)
            msg = PoseStamped()
            msg.header.frame_id = "map"
            msg.pose.position.x, msg.pose.position.y = sx, sy
            msg.pose.orientation.w = 1.0
            pub.publish(msg)
            t0 = rospy.get_time()
            while rospy.get_time() - t0 < 120 and not rospy.is_shutdown() and \
                    math.hypot(self.truth[0] - sx, self.truth[1] - sy) > REACHED:
                rospy.sleep(0.5)
            err = math.hypot(self.truth[0] - sx, self.truth[1] - sy)
            report.append(f"simple goal ({sx}, {sy}): final error {err:.2f} m")
            self.assertLessEqual(err, REACHED, report[-1])
        if max_contacts >= 0:
            self.assertLessEqual(self.contacts, max_contacts, "contacts: %d" % self.contacts)
        self.assertGreater(self.plans, 0, "nothing published on move_base/plan")
        sys.stderr.write("\n".join(report) + "\n")

    def on_truth(self, msg):
        p = msg.pose.pose
        self.truth = (p.position.x, p.position.y)

    def on_contacts(self, msg):
        self.contacts = msg.data

    def on_status(self, msg):
        import json
        st = json.loads(msg.data)
        self.contacts = int(st["wall_contacts"]) + int(st["robot_contacts"])

    def on_plan(self, _msg):
        self.plans += 1


if __name__ == "__main__":
    rospy.init_node("nav_goals_check")
    rostest.rosrun("spqrel_nav_lite", "nav_goals_check", NavGoals, sys.argv)
