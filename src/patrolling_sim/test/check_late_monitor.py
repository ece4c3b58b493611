#!/usr/bin/python3
"""rostest checker: the agents start ~5 s before the monitor, keep announcing, and GO still
happens; then the monitor gets SIGINT and must leave a complete info.csv and a flushed
idleness.csv. The run was stopped from outside: its status is INTERRUPTED (the original wrote
TIMEOUT here; docs/monitor.md)."""
import os
import signal
import sys
import time
import unittest

import rospy
import rostest

import patrol_test_utils as U


class TestLateMonitorAndSigint(unittest.TestCase):
    def test_late_monitor_then_sigint(self):
        n = rospy.get_param("~team_size")
        results_dir = rospy.get_param("~results_dir")
        rec = U.ResultsRecorder()
        rec.wait_for(lambda: rec.first(U.GO) is not None, 60, "GO from the late monitor")
        t_go = rec.first(U.GO)
        announces = [(t, d) for t, d in rec.of_type(10) if d[0] >= 0 and t < t_go]
        t_first = min(t for t, _ in announces)
        # re-announced while the monitor was missing: several [i,10,1] per robot, >= 4 s
        self.assertGreaterEqual(t_go - t_first, 3.0, "GO came too early: monitor not late?")
        for i in range(n):
            mine = [t for t, d in announces if d[0] == i]
            self.assertGreaterEqual(len(mine), 2, f"robot {i} announced {len(mine)} times")
        # the run goes on: wait for some visits by every robot
        rec.wait_for(lambda: all(len([1 for t, d in rec.of_type(11, i) if t > t_go]) >= 8
                                 for i in range(n)), 60, "visits after GO")
        prefix = U.find_result_files(results_dir, need_info=False)
        self.assertFalse(os.path.exists(prefix + "_info.csv"))
        pid = U.node_pid("/monitor")
        os.kill(pid, signal.SIGINT)
        prefix = U.find_result_files(results_dir, timeout=15)
        info = U.check_info_line(self, U.read(prefix + "_info.csv"))
        self.assertEqual(info[13], "INTERRUPTED")
        self.assertEqual(info[6], "RAND")
        self.assertEqual(int(info[1]), n)
        rows = U.check_idleness_file(self, U.read(prefix + "_idleness.csv"))
        # every sample is one idleness row and one (-1-based) visit: file fully flushed
        self.assertEqual(int(info[19]), len(rows))
        self.assertGreater(len(rows), 0)
        self.assertGreater(float(info[10]), 0.0)
        # the monitor process has exited
        end = time.time() + 10
        while time.time() < end:
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.2)
        else:
            self.fail("monitor still running 10 s after SIGINT")


if __name__ == "__main__":
    rospy.init_node("check_late_monitor")
    rostest.rosrun("patrolling_sim", "check_late_monitor", TestLateMonitorAndSigint, sys.argv)
