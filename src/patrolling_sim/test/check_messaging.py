#!/usr/bin/python3
"""rostest checker for the agents' algorithm messages (no monitor: the checker gives GO).

~lost (bool): with /lost_message_rate 1.0 no algorithm message (type >= 30) may appear on
/results while the 10/11 messages still flow. Otherwise every algorithm message [i,31,v]
must follow robot i's [i,11,v] by at least /communication_delay (and by less than that + 5 s).
"""
import sys
import time
import unittest

import rospy
import rostest

import patrol_test_utils as U


class TestMessaging(unittest.TestCase):
    def test_messages(self):
        n = rospy.get_param("~team_size")
        lost = rospy.get_param("~lost")
        duration = rospy.get_param("~duration", 8.0)
        delay = float(rospy.get_param("/communication_delay"))
        rec = U.ResultsRecorder()
        rec.wait_for(lambda: {d[0] for t, d in rec.of_type(10)} >= set(range(n)), 60,
                     "announcements of every robot")
        rec.send(U.GO)
        time.sleep(duration)
        rec.send(U.END)
        time.sleep(0.5)
        msgs = rec.snapshot()
        alg = [(t, d) for t, d in msgs if d[1] >= 30]
        for i in range(n):
            self.assertGreaterEqual(len(rec.of_type(11, i)), 4, f"robot {i}: too few visits")
        if lost:
            self.assertEqual(alg, [], "algorithm messages got through at loss rate 1.0")
            return
        self.assertGreater(len(alg), 2 * n)
        for i in range(n):
            reached = [(t, d[2]) for t, d in rec.of_type(11, i)]
            sent = [(t, d[2]) for t, d in alg if d[0] == i]
            self.assertGreater(len(sent), 0)
            # one algorithm message per reported vertex, in the same order, each delayed
            for k, (t_msg, v) in enumerate(sent):
                t_rep, v_rep = reached[k]
                self.assertEqual(v, v_rep, f"robot {i} message {k}")
                self.assertGreaterEqual(t_msg - t_rep, delay - 0.05,
                                        f"robot {i} message {k} not delayed")
                self.assertLess(t_msg - t_rep, delay + 5.0, f"robot {i} message {k} late")


if __name__ == "__main__":
    rospy.init_node("check_messaging")
    rostest.rosrun("patrolling_sim", "check_messaging", TestMessaging, sys.argv)
