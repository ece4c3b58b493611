#!/usr/bin/python3
"""rostest checker: the monitor's termination rules and both nodes' bad-input handling.

The checker starts monitors (and agents) as subprocesses one after another and plays
robot 0 of a one-robot team itself:
- FAIL: the robot goes silent longer than ~dead_robot_timeout;
- ABORT: /simulation_abort set true;
- TIMEOUT: ~timeout sim seconds after GO;
- STOPPED: /simulation_running set false;
each ends with END [-1,10,999] on /results, a 22-field info.csv with that termination and
exit status 0. Bad input: one-line error naming the problem, exit status 2 (1 for a missing
/initial_pos).
"""
import glob
import os
import subprocess
import sys
import tempfile
import time
import unittest

import rospy
import rostest

import patrol_test_utils as U

ROSRUN = ["rosrun", "patrolling_sim"]


def run_node(args, timeout=30):
    return subprocess.run(ROSRUN + args, capture_output=True, text=True, timeout=timeout)


class TestNodeCli(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.rec = U.ResultsRecorder()
        cls.tmp = tempfile.mkdtemp(prefix="node_cli_", dir=os.environ.get("ROS_HOME"))

    def _monitor_run(self, name, extra, action):
        """Start a monitor for 1 robot, announce, get GO, report a visit, then ``action``;
        returns (info fields, time from GO to END, process)."""
        rdir = os.path.join(self.tmp, name)
        proc = subprocess.Popen(ROSRUN + ["monitor", "grid", "CR", "1", f"__name:=mon_{name}",
                                          f"_results_dir:={rdir}"] + extra,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            n0 = len(self.rec.snapshot())
            end = time.time() + 30
            go = None
            while time.time() < end and go is None:
                self.rec.send([0, 10, 1])
                time.sleep(0.3)
                go = next((t for t, d in self.rec.snapshot()[n0:] if d == U.GO), None)
            self.assertIsNotNone(go, f"{name}: no GO")
            self.rec.send([0, 11, 0])
            action()
            self.rec.wait_for(lambda: any(d == U.END for t, d in self.rec.snapshot()[n0:]), 30,
                              f"{name}: END")
            t_end = next(t for t, d in self.rec.snapshot()[n0:] if d == U.END)
            out, err = proc.communicate(timeout=20)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        self.assertEqual(proc.returncode, 0, err[-2000:])
        self.assertIn("Info file", out)
        infos = glob.glob(os.path.join(rdir, "**", "*_info.csv"), recursive=True)
        self.assertEqual(len(infos), 1, infos)
        return U.check_info_line(self, U.read(infos[0])), t_end - go, proc

    def test_fail_dead_robot(self):
        info, dt, _ = self._monitor_run("fail", ["_dead_robot_timeout:=2.0"], lambda: None)
        self.assertEqual(info[13], "FAIL")
        # the monitor's own clock is authoritative; the checker may only have caught a
        # repeated GO (sent 3 times 0.5 s apart and on late announcements), so its wall
        # interval GO -> END can be up to ~1 s shorter
        self.assertGreaterEqual(float(info[10]), 2.0)
        self.assertGreaterEqual(dt, 1.0)

    def test_abort(self):
        info, _, _ = self._monitor_run(
            "abort", [], lambda: rospy.set_param("/simulation_abort", True))
        self.assertEqual(info[13], "ABORTED")      # the original writes ABORT (docs/monitor.md)
        rospy.set_param("/simulation_abort", False)

    def test_timeout(self):
        info, dt, _ = self._monitor_run("timeout", ["_timeout:=2.5"], lambda: None)
        self.assertEqual(info[13], "TIMEOUT")
        self.assertGreaterEqual(float(info[10]), 2.5)   # monitor's clock: see above
        self.assertGreaterEqual(dt, 1.5)
        self.assertLess(dt, 15.0)

    def test_stopped(self):
        info, _, _ = self._monitor_run(
            "stopped", [], lambda: rospy.set_param("/simulation_running", False))
        self.assertEqual(info[13], "STOPPED")

    def _one_line_error(self, proc, code, *words):
        self.assertEqual(proc.returncode, code, proc.stderr[-2000:])
        lines = [ln for ln in proc.stderr.splitlines() if ": error: " in ln]
        self.assertEqual(len(lines), 1, proc.stderr)
        for w in words:
            self.assertIn(w, lines[0])

    def test_monitor_bad_args(self):
        self._one_line_error(run_node(["monitor", "grid", "CR", "0", "__name:=m_bad1"]), 2,
                             "N", ">= 1")
        self._one_line_error(run_node(["monitor", "nosuchmap", "CR", "2", "__name:=m_bad2"]),
                             2, "nosuchmap")
        self._one_line_error(run_node(["monitor", "grid", "CR", "__name:=m_bad3"]), 2, "usage")

    def test_agent_bad_input(self):
        rospy.set_param("/initial_pos", [1.425, 24.375])
        self._one_line_error(run_node(["patrol_agent", "grid", "0", "_algorithm:=NOPE",
                                       "__name:=a_bad1"]), 2, "NOPE", "known:", "CR")
        self._one_line_error(run_node(["patrol_agent", "grid", "0", "__name:=a_bad2"]), 2,
                             "~algorithm")
        self._one_line_error(run_node(["patrol_agent", "grid", "3", "_algorithm:=CR",
                                       "__name:=a_bad3"]), 2, "/initial_pos")
        self._one_line_error(run_node(["patrol_agent", "nosuchmap", "0", "_algorithm:=CR",
                                       "__name:=a_bad4"]), 2, "nosuchmap")
        rospy.delete_param("/initial_pos")
        self._one_line_error(run_node(["patrol_agent", "grid", "0", "_algorithm:=CR",
                                       "__name:=a_bad5"]), 1, "/initial_pos")


if __name__ == "__main__":
    rospy.init_node("check_node_cli")
    rostest.rosrun("patrolling_sim", "check_node_cli", TestNodeCli, sys.argv)
