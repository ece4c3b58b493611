#!/usr/bin/python3
"""rostest checker for initial_poses_node: the latched PoseArray and /initial_pos agree,
hold the expected number of robots, lie on free cells of the map and are >= 0.5 m apart."""
import math
import sys
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseArray

from patrolling_sim.model import map_bundle


class TestInitialPoses(unittest.TestCase):
    def test_pose_array(self):
        n = rospy.get_param("~expected_count")
        msg = rospy.wait_for_message("/initial_poses", PoseArray, timeout=30)
        self.assertEqual(msg.header.frame_id, "map")
        self.assertEqual(len(msg.poses), n)
        flat = rospy.get_param("/initial_pos")
        self.assertEqual(len(flat), 2 * n)
        occ, _ = map_bundle.load_map_bundle("grid")
        pts = [(p.position.x, p.position.y) for p in msg.poses]
        for k, (x, y) in enumerate(pts):
            self.assertAlmostEqual(flat[2 * k], x, places=6)
            self.assertAlmostEqual(flat[2 * k + 1], y, places=6)
            self.assertTrue(occ.is_free(x, y), (k, x, y))
        for i in range(n):
            for j in range(i + 1, n):
                self.assertGreaterEqual(math.dist(pts[i], pts[j]), 0.5)


if __name__ == "__main__":
    rospy.init_node("check_initial_poses")
    rostest.rosrun("patrolling_sim", "check_initial_poses", TestInitialPoses, sys.argv)
