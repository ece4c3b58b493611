"""fake_localization (per robot): map -> odom tf and amcl_pose from the ground-truth pose.

Subscribes base_pose_ground_truth and odom (nav_msgs/Odometry); the correction is
map->odom = ground_truth o odom(at the same stamp)^-1, so odometry drift is removed.
"""
import collections
import functools
import threading

import rospy
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry

from spqrel_nav_lite.geometry import PoseHistory, compose, inverse
from spqrel_nav_lite.ros_util import (fill_pose, namespace_prefix, param, pose_of,
                                      strip_slash, transform_msg)


class FakeLocalization:
    """``ns``: parameter namespace (``"~"`` as a standalone node, ``"fake_localization/"``
    inside robot_nav). ``pose_listeners``: callables ``f(pose, stamp_sec)`` that receive
    every published pose in-process (robot_nav hands it to move_base this way). ``robot_ns``
    (``"/robot_3/"`` in nav_host): prefix of every topic and parameter name and of the
    robot's frames."""

    def __init__(self, ns="~", pose_listeners=(), robot_ns=""):
        if robot_ns:
            ns = robot_ns + ns
        self._p = functools.partial(param, ns=ns)
        self.pose_listeners = list(pose_listeners)
        r = robot_ns
        ns = robot_ns.strip("/") + "/" if robot_ns.strip("/") else namespace_prefix()
        self.global_frame = strip_slash(self._p("global_frame_id", "map", str))
        self.odom_frame = strip_slash(self._p("odom_frame_id", ns + "odom", str))
        self.base_frame = strip_slash(self._p("base_frame_id", ns + "base_link", str))
        self.delta = (self._p("delta_x", 0.0), self._p("delta_y", 0.0), self._p("delta_yaw", 0.0))
        self.odom = PoseHistory(horizon=5.0)
        #: ground-truth messages whose odometry has not come yet, oldest first
        self.pending = collections.deque()
        self.lock = threading.Lock()
        self.tf = tf2_ros.TransformBroadcaster()
        self.pose_pub = rospy.Publisher(r + "amcl_pose", PoseWithCovarianceStamped, queue_size=1)
        rospy.Subscriber(r + "odom", Odometry, self.on_odom, queue_size=5, tcp_nodelay=True)
        rospy.Subscriber(r + "base_pose_ground_truth", Odometry, self.on_truth, queue_size=1,
                         tcp_nodelay=True)

    def on_odom(self, msg):
        with self.lock:
            self._on_odom(msg)

    def on_truth(self, msg):
        with self.lock:
            self._on_truth(msg)

    def _on_odom(self, msg):
        self.odom.add(msg.header.stamp.to_sec(), pose_of(msg.pose.pose))
        while self.pending and self.pending[0].header.stamp <= msg.header.stamp:
            self.publish(self.pending.popleft())

    def _on_truth(self, msg):
        """Publish the correction for ``msg`` once the odometry of its instant is here.

        Odometry and ground truth come on two connections, so under load the ground truth
        of a step can come before its odometry, even by several steps. Each such message
        waits, in order, until the odometry reaches its stamp: a correction built from an
        older odometry pose would be off by the robot's motion in between. A message that
        waited longer than the odometry history (5 s of stamps) is dropped."""
        stamp = msg.header.stamp.to_sec()
        if self.pending and self.pending[-1].header.stamp.to_sec() > stamp:
            self.pending.clear()                      # time went backwards: a new run
        latest = self.odom.latest()
        if latest is None or latest[0] < stamp:
            self.pending.append(msg)
            while self.pending[0].header.stamp.to_sec() < stamp - self.odom.horizon:
                self.pending.popleft()
            return
        while self.pending:                           # older ones first (their odometry is
            self.publish(self.pending.popleft())     # here too: it is older than latest)
        self.publish(msg)

    def publish(self, msg):
        stamp = msg.header.stamp
        odom = self.odom.at(stamp.to_sec())
        if odom is None:
            return
        truth = compose(pose_of(msg.pose.pose), self.delta) if any(self.delta) \
            else pose_of(msg.pose.pose)
        # a message is built only for a topic someone subscribes to (neither is latched, so
        # nothing changes for subscribers): in nav_host and robot_nav move_base takes the
        # pose in-process, /tf often has no subscriber in a run, and building the two
        # messages costs a few tenths of a millisecond per ground-truth message
        if self.tf.pub_tf.get_num_connections():
            correction = compose(truth, inverse(odom))
            self.tf.sendTransform(transform_msg(correction, stamp, self.global_frame,
                                                self.odom_frame))
        if self.pose_pub.get_num_connections():
            out = PoseWithCovarianceStamped()
            out.header.stamp = stamp
            out.header.frame_id = self.global_frame
            fill_pose(out.pose.pose, truth)
            self.pose_pub.publish(out)
        for f in self.pose_listeners:
            f(truth, stamp.to_sec())


def main():
    rospy.init_node("fake_localization")
    FakeLocalization()
    rospy.spin()
