#!/usr/bin/python3
"""rostest checker: with /use_sim_time true and a clock 4x faster than wall time, the
agents' timers and the monitor's ~timeout run on sim time: the run ends by itself with
TIMEOUT after ~timeout sim seconds, in much less wall time, and results.txt/info.csv report
both durations."""
import sys
import unittest

import rospy
import rostest

import patrol_test_utils as U


class TestSimTime(unittest.TestCase):
    def test_sim_time_run(self):
        timeout = float(rospy.get_param("~timeout"))
        rec = U.ResultsRecorder()
        rec.wait_for(lambda: rec.first(U.END) is not None, 90, "END from the monitor")
        prefix = U.find_result_files(rospy.get_param("~results_dir"))
        info = U.check_info_line(self, U.read(prefix + "_info.csv"))
        self.assertEqual(info[13], "TIMEOUT")
        sim, real = float(info[10]), float(info[11])
        self.assertGreaterEqual(sim, timeout)
        self.assertLess(sim, timeout + 5.0)
        self.assertLess(real, sim / 2.0, "the monitor did not measure sim time")
        self.assertGreater(int(info[19]), 0)
        t_go, t_end = rec.first(U.GO), rec.first(U.END)
        self.assertGreaterEqual(t_end - t_go, timeout - 0.5)   # ROS (sim) time of /results


if __name__ == "__main__":
    rospy.init_node("check_sim_time")
    rostest.rosrun("patrolling_sim", "check_sim_time", TestSimTime, sys.argv)
