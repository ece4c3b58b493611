#!/usr/bin/python3
"""rostest: two robots (robot_0, robot_1) swap places through the same corridor at the same
time. Passes if both SUCCEED with the simulator's contact count at 0, or if every goal that
did not succeed ended ABORTED with a reason (and still no robot-robot contact). The outcome
is reported on stderr and in the log.

~goals: "x0 y0; x1 y1" (goal of robot_0; goal of robot_1).
"""
import json
import sys
import unittest

import actionlib
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from std_msgs.msg import String


class HeadOn(unittest.TestCase):
    def test_head_on(self):
        goals = [tuple(float(v) for v in p.split()) for p in rospy.get_param("~goals").split(";")]
        self.status = None
        rospy.Subscriber("/stage2d/status", String, self.on_status)
        clients = [actionlib.SimpleActionClient(f"/robot_{i}/move_base", MoveBaseAction)
                   for i in range(2)]
        for c in clients:
            self.assertTrue(c.wait_for_server(rospy.Duration(60)), "no move_base")
        rospy.sleep(1.0)
        for c, (gx, gy) in zip(clients, goals):
            g = MoveBaseGoal()
            g.target_pose.header.frame_id = "map"
            g.target_pose.pose.position.x, g.target_pose.pose.position.y = gx, gy
            g.target_pose.pose.orientation.w = 1.0
            c.send_goal(g)
        for c in clients:
            self.assertTrue(c.wait_for_result(rospy.Duration(300)), "no result")
        rospy.sleep(2.5)            # one more status message
        states = [c.get_state() for c in clients]
        texts = [c.get_goal_status_text() for c in clients]
        st = json.loads(self.status) if self.status else {}
        robot_contacts = st.get("robot_contacts", -1)
        wall_contacts = st.get("wall_contacts", -1)
        both = all(s == GoalStatus.SUCCEEDED for s in states)
        msg = (f"head-on: {'both reached their goals' if both else 'not both reached'}; states "
               f"{states} {texts}; robot contacts {robot_contacts}, wall contacts {wall_contacts}")
        rospy.loginfo(msg)
        sys.stderr.write(msg + "\n")
        self.assertGreaterEqual(robot_contacts, 0, "no simulator status")
        if both:
            self.assertEqual(robot_contacts + wall_contacts, 0, msg)
        else:
            for s, t in zip(states, texts):
                self.assertIn(s, (GoalStatus.SUCCEEDED, GoalStatus.ABORTED), msg)
                if s == GoalStatus.ABORTED:
                    self.assertTrue(len(t) > 5, msg)
            self.assertEqual(robot_contacts, 0, msg)

    def on_status(self, msg):
        self.status = msg.data


if __name__ == "__main__":
    rospy.init_node("check_head_on")
    rostest.rosrun("spqrel_nav_lite", "check_head_on", HeadOn, sys.argv)
