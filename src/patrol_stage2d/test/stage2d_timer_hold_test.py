#!/usr/bin/python3
"""Timer hold (timer_hold.h, ~timer_wait): the simulator sets /sim_timers_reader, and a
reporter on /sim_timers whose earliest deadline is T keeps the clock at the first step at
or after T until it reports that the timer fired; then the clock moves on.

Load-proof: ~timer_wait is 30 wall s here, and every check waits for an event (bounded)
instead of timing the simulator."""
import json
import time
import unittest

import rospy
import rostest
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String

STEP = 0.1              # the simulator's default step (sim s)


class TimerHoldTest(unittest.TestCase):
    def test_the_clock_waits_at_a_due_timer_until_it_fired(self):
        rospy.init_node("stage2d_timer_hold_test")
        latest = {}
        rospy.Subscriber("/clock", Clock, lambda m: latest.update(t=m.clock.to_sec()),
                         tcp_nodelay=True)
        statuses = []
        rospy.Subscriber("/stage2d/status", String, lambda m: statuses.append(json.loads(m.data)))
        pub = rospy.Publisher("/sim_timers", Float64MultiArray, queue_size=10)

        def until(cond, what, timeout=20.0):
            end = time.time() + timeout
            while not cond():
                self.assertLess(time.time(), end, what)
                time.sleep(0.01)

        until(lambda: rospy.get_param("/sim_timers_reader", False), "reader parameter not set")
        until(lambda: pub.get_num_connections() > 0 and "t" in latest, "no connection, no clock")
        deadline = latest["t"] + 1.0
        pub.publish(Float64MultiArray(data=[latest["t"], deadline]))
        until(lambda: latest["t"] >= deadline - 1e-6, "the clock never reached the deadline")
        held_at = latest["t"]
        self.assertLess(held_at, deadline + STEP + 1e-6, "the clock ran past the deadline's step")
        time.sleep(1.0)                     # five sim s at x5 if it did not wait
        self.assertEqual(latest["t"], held_at, "the clock moved on before the report")
        pub.publish(Float64MultiArray(data=[held_at, -1.0]))
        until(lambda: latest["t"] > held_at + 1e-6, "the clock did not move on after the report")
        n = len(statuses)
        until(lambda: len(statuses) > n, "no /stage2d/status")
        timer = statuses[-1]["hold_reasons"]["timer"]
        self.assertGreaterEqual(timer["holds"], 1, statuses[-1])
        self.assertEqual(timer["timeouts"], 0, statuses[-1])


if __name__ == "__main__":
    rostest.rosrun("patrol_stage2d", "stage2d_timer_hold", TimerHoldTest)
