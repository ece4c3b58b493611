#!/usr/bin/python3
"""rostest checker for the agent's failure path: goals to one vertex are aborted by the
stand-in move_base; the agent backs up (cmd_vel), clears costmaps, resends the same goal
exactly 3 times, then lets the strategy choose another vertex and goes on patrolling."""
import math
import sys
import threading
import time
import unittest

import rospy
import rostest
from move_base_msgs.msg import MoveBaseActionGoal

import patrol_test_utils as U
from patrolling_sim.common import paths
from patrolling_sim.model.graph import PatrolGraph, load_graph


class TestGoalFailure(unittest.TestCase):
    def test_failure_path(self):
        bad = rospy.get_param("~abort_vertex")
        g = PatrolGraph(load_graph(paths.map_files("grid")[1]))
        goals, lock = [], threading.Lock()

        def on_goal(msg):
            p = msg.goal.target_pose.pose.position
            v = min(range(g.n), key=lambda k: math.hypot(g.pos[k][0] - p.x, g.pos[k][1] - p.y))
            with lock:
                goals.append((rospy.get_time(), v))

        rospy.Subscriber("/robot_0/move_base/goal", MoveBaseActionGoal, on_goal)
        rec = U.ResultsRecorder()
        rec.wait_for(lambda: rec.of_type(10, 0), 60, "announcement of robot 0")
        time.sleep(0.5)
        rec.send(U.GO)

        def gave_up():
            with lock:
                seq = [v for _, v in goals]
            # a run of goals to the bad vertex, then a different goal, then 3 more visits
            for k in range(len(seq) - 1):
                if seq[k] == bad and seq[k + 1] != bad:
                    t_after = goals[k + 1][0]
                    return len([1 for t, d in rec.of_type(11, 0) if t > t_after]) >= 3
            return False

        rec.wait_for(gave_up, 60, "the agent to give up on the aborting vertex and move on")
        with lock:
            seq = [v for _, v in goals]
        runs, k = [], 0
        while k < len(seq):
            if seq[k] == bad:
                j = k
                while j < len(seq) and seq[j] == bad:
                    j += 1
                runs.append(j - k)
                k = j
            else:
                k += 1
        # first complete run: the original goal + 3 resends
        complete = runs[:-1] if seq[-1] == bad else runs
        self.assertTrue(complete, seq)
        self.assertEqual(complete[0], 4, f"goal sequence {seq}")
        self.assertNotIn(bad, [d[2] for t, d in rec.of_type(11, 0)])
        time.sleep(1.2)                    # fake_move_base updates its counters at 1 Hz
        stats = rospy.get_param("/fake_move_base/stats/robot_0")
        self.assertGreaterEqual(stats["aborted"], 4, stats)
        self.assertGreaterEqual(stats["clear_costmaps"], 1 + 4, stats)   # start + failures
        self.assertGreaterEqual(stats["cmd_vel"], 3 * 4, stats)          # back-up twists


if __name__ == "__main__":
    rospy.init_node("check_goal_failure")
    rostest.rosrun("patrolling_sim", "check_goal_failure", TestGoalFailure, sys.argv)
