#!/usr/bin/python3
"""rostest checker: a DTA team (DTAG or DTAP, one patrol_agent node per robot) patrols grid
in the abstract world until the monitor's timeout. Checks that every robot broadcasts its
type-40 idleness estimates (length V+3, int16 tenths of seconds), that DTAP robots auction
(type 41) and answer with better bids (type 42 for a vertex that was auctioned), that every
vertex is visited, and that the run ends on the monitor's TIMEOUT with its files written.

Private parameters: ~team_size, ~alg, ~msg_types (list: types that must be seen), ~vertices,
~results_dir, ~run_timeout (wall s, a safety net only), ~positions (bool: /positions from
every robot expected, i.e. the world sends move_base feedback)."""
import sys
import time
import unittest

import rospy
import rostest
from nav_msgs.msg import Odometry

import patrol_test_utils as U

DTA_IDLENESS, SSI_TASK_REQUEST, SSI_BID = 40, 41, 42


class TestDtaRun(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.n = rospy.get_param("~team_size")
        cls.v = rospy.get_param("~vertices")
        cls.results_dir = rospy.get_param("~results_dir")
        cls.rec = U.ResultsRecorder()
        cls.positions = set()
        rospy.Subscriber("/positions", Odometry,
                         lambda m: cls.positions.add(m.header.frame_id))
        cls.rec.wait_for(lambda: cls.rec.first(U.END) is not None,
                         rospy.get_param("~run_timeout", 150), "END from the monitor")
        time.sleep(1.0)
        # the checker may start after GO (nine nodes start at once); before GO agents send
        # only type 10, so without a GO seen every message counts
        go = cls.rec.first(U.GO)
        cls.t_go = go if go is not None else float("-inf")

    def after_go(self, kind):
        return [d for t, d in self.rec.of_type(kind) if t >= self.t_go]

    def test_every_vertex_visited_by_the_team(self):
        visits = self.after_go(11)
        self.assertEqual({d[2] for d in visits}, set(range(self.v)))
        for i in range(self.n):
            self.assertGreaterEqual(sum(1 for d in visits if d[0] == i), 5, f"robot {i}")

    def test_idleness_estimates_from_every_robot(self):
        msgs = self.after_go(DTA_IDLENESS)
        self.assertEqual({d[0] for d in msgs}, set(range(self.n)))
        for d in msgs:
            self.assertEqual(len(d), self.v + 3, d)
            self.assertTrue(all(0 <= x <= 32767 for x in d[2:2 + self.v]), d)
            self.assertIn(d[-1], range(self.v), d)          # the sender's next goal

    def test_auctions(self):
        kinds = rospy.get_param("~msg_types")
        for kind in kinds:
            self.assertTrue(self.after_go(kind), f"no type-{kind} message")
        if SSI_BID in kinds:
            auctioned = {d[2] for d in self.after_go(SSI_TASK_REQUEST)}
            for d in self.after_go(SSI_BID):
                self.assertIn(d[2], auctioned, f"bid {d} for a vertex nobody auctioned")
        else:
            self.assertEqual(self.after_go(SSI_TASK_REQUEST) + self.after_go(SSI_BID), [])

    def test_positions(self):
        if rospy.get_param("~positions", False):
            self.assertEqual(self.positions, {f"robot_{i}/map" for i in range(self.n)})

    def test_run_ended_on_timeout(self):
        prefix = U.find_result_files(self.results_dir)
        info = U.check_info_line(self, U.read(prefix + "_info.csv"))
        self.assertEqual(info[6], rospy.get_param("~alg"))
        self.assertEqual(info[13], "TIMEOUT")
        self.assertGreaterEqual(float(info[10]), rospy.get_param("~sim_timeout"))


if __name__ == "__main__":
    rospy.init_node("check_dta_run")
    rostest.rosrun("patrolling_sim", "check_dta_run", TestDtaRun, sys.argv)
