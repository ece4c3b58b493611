#!/usr/bin/python3
"""Command-synchronised stepping (~sync_timeout): the simulator, asked to run as fast as
possible, waits for a slow controller's next command before each step (so that controller's
commands are never stale), and goes back to full speed when the controller stops (a dead
node is waited for at most once).

Load-proof checks only: while the controller runs, the sim cannot run faster than one step per
command (an upper bound: load only slows things down) and the simulator's own counters (sync
waits, stale commands: sim-time results) show the waiting; after it stops, the simulator keeps
stepping and waits no more."""
import json
import sys
import threading
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import Twist
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

DELAY = 0.02            # wall seconds the controller takes per command


class SyncTest(unittest.TestCase):
    def test_waits_for_a_slow_controller_then_runs_free(self):
        rospy.init_node("stage2d_sync_test")
        pub = rospy.Publisher("/robot_0/cmd_vel", Twist, queue_size=1)
        state = {"on": True, "samples": []}
        lock = threading.Lock()

        def on_clock(m):
            with lock:
                state["samples"].append((time.time(), m.clock.to_sec()))
            if state["on"]:
                time.sleep(DELAY)           # a slow controller: 20 ms per command
                t = Twist()
                t.angular.z = 0.5
                pub.publish(t)

        rospy.Subscriber("/clock", Clock, on_clock, queue_size=1, tcp_nodelay=True)
        statuses = []
        rospy.Subscriber("/stage2d/status", String, lambda m: statuses.append(json.loads(m.data)))
        t_end = time.time() + 20
        while not state["samples"] and time.time() < t_end:
            time.sleep(0.05)
        self.assertTrue(state["samples"], "no /clock")

        def pace(settle, window):
            """Simulated seconds per wall second over ``window`` s, after ``settle`` s."""
            time.sleep(settle)
            with lock:
                w0, s0 = state["samples"][-1]
            time.sleep(window)
            with lock:
                w1, s1 = state["samples"][-1]
            return (s1 - s0) / (w1 - w0)

        def next_status():
            n = len(statuses)
            t_end = time.time() + 20
            while len(statuses) == n and time.time() < t_end:
                time.sleep(0.05)
            self.assertGreater(len(statuses), n, "no /stage2d/status")
            return statuses[-1]

        paced = pace(2.0, 4.0)              # connections up, robot being driven
        st = next_status()
        # one 0.1 s step per command, each >= 20 ms: at most ~5x real time
        self.assertLess(paced, 6.0, f"did not wait for the controller: {paced:.1f}x, {st}")
        self.assertGreater(st["sync_waits"], 10, st)
        self.assertLess(st["stale_command_fraction"], 0.1, st)
        # the controller stops: after at most one wait the simulator steps on without waiting
        state["on"] = False
        time.sleep(1.0)
        st1 = next_status()
        st2 = next_status()
        self.assertEqual(st2["sync_waits"], st1["sync_waits"], f"still waiting: {st1} -> {st2}")
        self.assertGreater(st2["steps"] - st1["steps"], 20, f"not stepping: {st1} -> {st2}")


if __name__ == "__main__":
    rostest.rosrun("patrol_stage2d", "stage2d_sync", SyncTest, sys.argv)
