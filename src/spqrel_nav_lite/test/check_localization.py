#!/usr/bin/python3
"""rostest: localisation of robot_0 against the simulator's ground truth.

mode "fake": drives the robot with cmd_vel (odometry drifts), then checks that the tf
map->robot_0/odom composed with odom equals the ground truth, and that amcl_pose does.
mode "amcl": sends move_base goals (~goals "x y; x y") so the robot drives; checks that
amcl_pose converges (final error < ~max_err_xy / ~max_err_a; after ~converge_updates
updates the error must have dropped below ~converge_err; from then on the mean error
< ~mean_err_xy and the maximum < ~max_err_after), that particlecloud is published and
global_localization is served.
"""
import math
import sys
import unittest

import actionlib
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import Odometry
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from spqrel_nav_lite.geometry import compose, normalize_angle, yaw_from_quaternion


def pose_of(p):
    q = p.orientation
    return (p.position.x, p.position.y, yaw_from_quaternion(q.x, q.y, q.z, q.w))


class LocalizationTest(unittest.TestCase):
    def setUp(self):
        self.truth = {}
        self.odom = {}
        self.est = []
        self.clouds = 0
        #: stamps (ns) at which map->robot_0/odom was published: the fake localiser reads the
        #: ground truth with queue_size 1, so under load it skips some, and tf2 interpolates
        #: between its neighbours there (not an error of the localiser)
        self.corrections = set()
        rospy.Subscriber("/tf", TFMessage, self.on_tf, queue_size=100)
        rospy.Subscriber("/robot_0/base_pose_ground_truth", Odometry, self.on_truth)
        rospy.Subscriber("/robot_0/odom", Odometry, self.on_odom)
        rospy.Subscriber("/robot_0/amcl_pose", PoseWithCovarianceStamped, self.on_est)
        rospy.Subscriber("/robot_0/particlecloud", PoseArray, self.on_cloud)

    def on_truth(self, m):
        self.truth[m.header.stamp.to_nsec()] = pose_of(m.pose.pose)

    def on_tf(self, m):
        for t in m.transforms:
            if t.header.frame_id == "map" and t.child_frame_id == "robot_0/odom":
                self.corrections.add(t.header.stamp.to_nsec())

    def on_odom(self, m):
        self.odom[m.header.stamp.to_nsec()] = pose_of(m.pose.pose)

    def on_est(self, m):
        self.est.append((m.header.stamp.to_nsec(), pose_of(m.pose.pose)))

    def on_cloud(self, m):
        self.last_cloud = m
        self.clouds += 1

    def error(self, est, stamp):
        t = self.truth.get(stamp)
        if t is None:
            return None
        return math.hypot(est[0] - t[0], est[1] - t[1]), abs(normalize_angle(est[2] - t[2]))

    def test_localization(self):
        mode = rospy.get_param("~mode")
        if mode == "fake":
            self.run_fake()
        else:
            self.run_amcl()

    def run_fake(self):
        buf = tf2_ros.Buffer()
        tf2_ros.TransformListener(buf)
        pub = rospy.Publisher("/robot_0/cmd_vel", Twist, queue_size=1)
        rate = rospy.Rate(10)
        t0 = rospy.get_time()
        checked = 0
        max_corr_change = 0.0
        first_corr = None
        while rospy.get_time() - t0 < 20.0 and not rospy.is_shutdown():
            cmd = Twist()
            cmd.linear.x, cmd.angular.z = 0.4, (0.3 if rospy.get_time() - t0 < 10 else -0.3)
            pub.publish(cmd)
            rate.sleep()
            for stamp in sorted(self.odom)[-5:-2]:
                try:
                    tr = buf.lookup_transform("map", "robot_0/odom",
                                              rospy.Time(0, 0) + rospy.Duration(0, stamp) if False
                                              else rospy.Time.from_sec(stamp * 1e-9))
                except (tf2_ros.LookupException, tf2_ros.ExtrapolationException,
                        tf2_ros.ConnectivityException):
                    continue
                if stamp not in self.truth or stamp not in self.corrections:
                    continue
                c = (tr.transform.translation.x, tr.transform.translation.y,
                     yaw_from_quaternion(tr.transform.rotation.x, tr.transform.rotation.y,
                                         tr.transform.rotation.z, tr.transform.rotation.w))
                if first_corr is None:
                    first_corr = c
                max_corr_change = max(max_corr_change, math.hypot(c[0] - first_corr[0],
                                                                  c[1] - first_corr[1]),
                                      abs(normalize_angle(c[2] - first_corr[2])))
                exy, ea = self.error(compose(c, self.odom[stamp]), stamp)
                self.assertLess(exy, 0.01, f"map->odom o odom != truth at {stamp}: {exy:.3f} m")
                self.assertLess(ea, 0.01, f"yaw error {ea:.3f} rad")
                checked += 1
        pub.publish(Twist())
        self.assertGreater(checked, 20, "too few tf samples checked")
        self.assertGreater(max_corr_change, 0.01, "odometry drift not corrected (no change)")
        n = 0
        for stamp, est in self.est[-20:]:
            e = self.error(est, stamp)
            if e is not None:
                self.assertLess(e[0], 1e-3)
                n += 1
        self.assertGreater(n, 5, "amcl_pose missing")

    def run_amcl(self):
        goals = [tuple(float(v) for v in p.split()) for p in rospy.get_param("~goals").split(";")
                 if p.strip()]
        client = actionlib.SimpleActionClient("/robot_0/move_base", MoveBaseAction)
        self.assertTrue(client.wait_for_server(rospy.Duration(60)), "no move_base")
        for gx, gy in goals:
            g = MoveBaseGoal()
            g.target_pose.header.frame_id = "map"
            g.target_pose.pose.position.x, g.target_pose.pose.position.y = gx, gy
            g.target_pose.pose.orientation.w = 1.0
            client.send_goal(g)
            client.wait_for_result(rospy.Duration(200))
            rospy.loginfo("goal (%.2f, %.2f): state %d '%s'", gx, gy, client.get_state(),
                          client.get_goal_status_text())
        rospy.sleep(1.0)
        errs = [e for e in (self.error(p, s) for s, p in self.est) if e is not None]
        rospy.loginfo("error series (m): %s", " ".join(f"{e[0]:.2f}" for e in errs))
        self.assertGreater(len(errs), 10, f"only {len(errs)} amcl_pose updates")
        first = errs[0]
        # converged = first update with an error below ~converge_err; it must come within
        # ~converge_updates updates; the mean / max checks apply from there on
        conv_err = float(rospy.get_param("~converge_err", 0.25))
        limit = int(rospy.get_param("~converge_updates", len(errs) // 2))
        skip = next((k for k, e in enumerate(errs) if e[0] < conv_err), len(errs))
        self.assertLessEqual(skip, limit, f"not converged below {conv_err} m within {limit} "
                             f"updates")
        half = errs[skip:]
        mean_xy = sum(e[0] for e in half) / len(half)
        final = errs[-1]
        msg = (f"{len(errs)} updates; first error {first[0]:.2f} m {first[1]:.2f} rad; final "
               f"{final[0]:.3f} m {final[1]:.3f} rad; converged after {skip} updates; "
               f"then mean {mean_xy:.3f} m; "
               f"max {max(e[0] for e in half):.3f} m; sim time driven "
               f"{(self.est[-1][0] - self.est[0][0]) * 1e-9:.0f} s")
        rospy.loginfo(msg)
        sys.stderr.write(msg + "\n")
        self.assertLess(final[0], float(rospy.get_param("~max_err_xy", 0.3)), msg)
        self.assertLess(final[1], float(rospy.get_param("~max_err_a", 0.2)), msg)
        self.assertLess(mean_xy, float(rospy.get_param("~mean_err_xy", 0.2)), msg)
        self.assertLess(max(e[0] for e in half), float(rospy.get_param("~max_err_after", 0.5)),
                        msg)
        self.assertGreater(self.clouds, 0, "no particlecloud")
        # global localisation spreads the particles over the whole free space
        rospy.wait_for_service("/robot_0/global_localization", 5)
        before = self.clouds
        rospy.ServiceProxy("/robot_0/global_localization", Empty)()
        t0 = rospy.get_time()
        while self.clouds == before and rospy.get_time() - t0 < 10 and not rospy.is_shutdown():
            rospy.sleep(0.1)
        self.assertGreater(self.clouds, before, "no particlecloud after global_localization")
        xs = [p.position.x for p in self.last_cloud.poses]
        spread = max(xs) - min(xs)
        self.assertGreater(spread, 10.0, f"global_localization: particles span only {spread:.1f} m")


if __name__ == "__main__":
    rospy.init_node("check_localization")
    rostest.rosrun("spqrel_nav_lite", "check_localization", LocalizationTest, sys.argv)
