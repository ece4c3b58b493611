#!/usr/bin/python3
"""rostest checker: monitor + N PatrolAgents + fake move_base run until the monitor stops
after ~cycles complete cycles. Checks the handshake, visits, /positions, markers, END, the
agents' exit on END, and the four result files against the original's formats."""
import os
import sys
import threading
import time
import unittest

import rosgraph
import rospy
import rostest
from nav_msgs.msg import Odometry
from patrolling_sim.agent.core import ANNOUNCE_PERIOD
from visualization_msgs.msg import MarkerArray

import patrol_test_utils as U


class TestPatrolRun(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.n = rospy.get_param("~team_size")
        cls.cycles = rospy.get_param("~cycles")
        cls.results_dir = rospy.get_param("~results_dir")
        cls.rec = U.ResultsRecorder()
        cls.t_connected = None       # when /results had every publisher (agents, monitor)
        threading.Thread(target=cls._watch_connections, daemon=True).start()
        cls.positions = {}
        cls.markers = []
        rospy.Subscriber("/positions", Odometry, cls._pos)
        rospy.Subscriber("/patrol_graph_markers", MarkerArray, cls.markers.append)
        cls.rec.wait_for(lambda: cls.rec.first(U.END) is not None,
                         rospy.get_param("~run_timeout", 90), "END from the monitor")
        cls.t_end = cls.rec.first(U.END)
        time.sleep(2.0)              # anything after END would show up here

    @classmethod
    def _watch_connections(cls):
        # until this node's /results subscriber is connected to every other publisher (the
        # n agents and the monitor) an announcement may be missed: the checker starts after
        # the nodes, and under load it may connect only after GO
        while not rospy.is_shutdown() and cls.rec.first(U.GO) is None:
            try:
                if cls.rec.connected_to_publishers(cls.n + 1):
                    cls.t_connected = rospy.get_time()
                    return
            except (rosgraph.MasterException, OSError):
                pass                     # a node just left or the master is busy: look again
            time.sleep(0.1)

    @classmethod
    def _pos(cls, msg):
        cls.positions.setdefault(msg.header.frame_id, 0)
        cls.positions[msg.header.frame_id] += 1

    def test_handshake(self):
        t_go = self.rec.first(U.GO)
        self.assertIsNotNone(t_go, "no GO")
        # the checker may connect after the first announcements, or even after GO: every
        # announcement it saw came from a team member, before GO; if it was connected to
        # every publisher more than one announcement period (+ 0.5 s) before GO, it saw
        # every robot announce; and every robot reported its start after GO
        ready = {d[0] for t, d in self.rec.of_type(10) if d[0] >= 0}
        self.assertTrue(ready <= set(range(self.n)), ready)
        if self.t_connected is not None and self.t_connected <= t_go - ANNOUNCE_PERIOD - 0.5:
            self.assertEqual(ready, set(range(self.n)))
        self.assertTrue(all(t <= t_go + 0.5 for t, d in self.rec.of_type(10) if d[0] >= 0))
        starters = {d[0] for t, d in self.rec.of_type(11) if t >= t_go}
        self.assertEqual(starters, set(range(self.n)))

    def test_visits_reported_by_every_robot(self):
        t_go = self.rec.first(U.GO)
        visits = [(t, d) for t, d in self.rec.of_type(11) if t >= t_go]
        for i in range(self.n):
            mine = [d for t, d in visits if d[0] == i]
            self.assertGreaterEqual(len(mine), 3, f"robot {i} reported {len(mine)} visits")
        self.assertEqual({d[2] for t, d in visits}, set(range(25)))

    def test_agents_stop_after_end(self):
        late = [d for t, d in self.rec.of_type(11) if t > self.t_end + 0.5]
        self.assertEqual(late, [], "visits reported after END")

    def test_positions_published(self):
        for i in range(self.n):
            self.assertGreater(self.positions.get(f"robot_{i}/map", 0), 0, self.positions)

    def test_algorithm_messages_from_every_robot(self):
        """Algorithms that talk (e.g. SEBS type 32) reach the others, also when the agents
        share one process (~msg_type; 0 = not checked)."""
        kind = rospy.get_param("~msg_type", 0)
        if kind:
            senders = {d[0] for t, d in self.rec.of_type(kind)}
            self.assertEqual(senders, set(range(self.n)))

    def test_markers(self):
        self.assertTrue(self.markers, "no /patrol_graph_markers")
        m = self.markers[-1].markers
        self.assertEqual(sum(1 for x in m if x.ns == "vertices"), 25)
        self.assertEqual(sum(1 for x in m if x.ns == "edges"), 1)

    def test_result_files(self):
        prefix = U.find_result_files(self.results_dir)
        ref = U.reference_dir()
        ref_prefix = os.path.join(ref, "20261122_095832")
        # info.csv: 22 fields, termination CYCLES, cycles reached
        info = U.check_info_line(self, U.read(prefix + "_info.csv"))
        self.assertEqual(info[0], "grid")
        self.assertEqual(int(info[1]), self.n)
        self.assertEqual(info[6], rospy.get_param("~alg", "CR"))
        self.assertEqual(info[13], "CYCLES")
        self.assertEqual(int(info[21]), self.cycles)
        self.assertEqual(os.path.basename(prefix), info[9])
        # same shape as the original's line, field by field (except the variable texts)
        ref_info = U.read(ref_prefix + "_info.csv").rstrip("\n").split(";")
        for k in (1, 3, 4, 10, 11, 12, 14, 15, 16, 17, 18, 19, 20, 21):
            self.assertEqual(U.shape(info[k]), U.shape(ref_info[k]), f"field {k + 1}")
        # idleness.csv: header + rows, one per sample
        rows = U.check_idleness_file(self, U.read(prefix + "_idleness.csv"))
        self.assertGreater(len(rows), 0)
        self.assertEqual(U.read(prefix + "_idleness.csv").splitlines()[0],
                         U.read(ref_prefix + "_idleness.csv").splitlines()[0])
        # timeresults.csv: header only (run < 900 s), as in the original's example
        self.assertEqual(U.read(prefix + "_timeresults.csv"),
                         U.read(ref_prefix + "_timeresults.csv"))
        # results.txt: one block per cycle, same line shapes as the original (same map)
        text = U.read(prefix + "_results.txt")
        self.assertEqual(text.count("Complete Patrol Cycles:"), self.cycles)
        ours = [U.shape(x) for x in U.first_block(text)]
        theirs = [U.shape(x) for x in U.first_block(U.read(ref_prefix + "_results.txt"))]
        self.assertEqual(ours, theirs)
        self.assertTrue(text.startswith("\nComplete Patrol Cycles:\t1\n"))


if __name__ == "__main__":
    rospy.init_node("check_patrol_run")
    rostest.rosrun("patrolling_sim", "check_patrol_run", TestPatrolRun, sys.argv)
