#!/usr/bin/python3
"""rostest: /map (latched) and static_map match the yaml loaded by the core map loader."""
import sys
import unittest

import numpy as np
import rospy
import rostest
from nav_msgs.msg import MapMetaData, OccupancyGrid
from nav_msgs.srv import GetMap

from spqrel_nav_lite.mapio import load_map


class MapServerTest(unittest.TestCase):
    def setUp(self):
        self.ref = load_map(rospy.get_param("~map"))

    def check(self, msg, what):
        ref = self.ref
        self.assertEqual(msg.header.frame_id, "map", what)
        self.assertEqual((msg.info.width, msg.info.height), (ref.width, ref.height), what)
        self.assertAlmostEqual(msg.info.resolution, ref.resolution, places=6, msg=what)
        self.assertAlmostEqual(msg.info.origin.position.x, ref.origin[0], places=4, msg=what)
        self.assertAlmostEqual(msg.info.origin.position.y, ref.origin[1], places=4, msg=what)
        data = np.asarray(msg.data, dtype=np.int8).reshape(msg.info.height, msg.info.width)
        # a few named cells, then all of them
        for x, y in ((0.5, 0.5), (ref.size_m[0] / 2, ref.size_m[1] / 2),
                     (ref.size_m[0] - 0.3, ref.size_m[1] - 0.3)):
            i, j = ref.world_to_cell(x + ref.origin[0], y + ref.origin[1])
            self.assertEqual(data[j, i], ref.data[j, i], f"{what}: cell ({i},{j})")
        self.assertTrue(np.array_equal(data, ref.data), f"{what}: cells differ")
        self.assertTrue((data == 100).any() and (data == 0).any(), what)

    def test_topic(self):
        msg = rospy.wait_for_message("/map", OccupancyGrid, timeout=30)
        self.check(msg, "/map")
        meta = rospy.wait_for_message("/map_metadata", MapMetaData, timeout=10)
        self.assertEqual(meta.width, self.ref.width)

    def test_service(self):
        rospy.wait_for_service("/static_map", 30)
        self.check(rospy.ServiceProxy("/static_map", GetMap)().map, "static_map")


if __name__ == "__main__":
    rospy.init_node("check_map_server")
    rostest.rosrun("spqrel_nav_lite", "check_map_server", MapServerTest, sys.argv)
