"""Navigation outputs that are built only while someone subscribes: move_base's ~plan (with
the latest plan for a subscriber that comes later) and fake_localization's /tf and
amcl_pose. The glue is driven with stand-in publishers, without a ROS master."""
import collections
import math
import threading

import numpy as np
import pytest

rospy = pytest.importorskip("rospy", reason="rospy (Debian: python3-rospy) missing")
from geometry_msgs.msg import PoseWithCovarianceStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402

from spqrel_nav_lite.fake_localization_node import FakeLocalization  # noqa: E402
from spqrel_nav_lite.geometry import PoseHistory  # noqa: E402
from spqrel_nav_lite.move_base_node import MoveBase, _PlanOnSubscribe  # noqa: E402


@pytest.fixture(autouse=True)
def ros_time():
    """rospy.Time.now() without a node: wall time."""
    rospy.rostime.set_rostime_initialized(True)
    yield


class Pub:
    """A publisher with ``connections`` subscribers; records what it publishes."""

    def __init__(self, connections=0):
        self.connections = connections
        self.sent = []

    def get_num_connections(self):
        return self.connections

    def publish(self, msg):
        self.sent.append(msg)


def move_base(connections):
    mb = MoveBase.__new__(MoveBase)         # the glue only: no map, no planner, no node
    mb.global_frame = "map"
    mb.last_path = None
    mb.plan_pub = Pub(connections)
    mb.built = 0
    real = MoveBase.plan_msg

    def counting(path):
        mb.built += 1
        return real(mb, path)
    mb.plan_msg = counting
    return mb


PATH = np.array([[0.0, 0.0], [0.5, 0.1], [1.0, 0.3]])


def test_a_plan_is_built_only_while_someone_subscribes():
    mb = move_base(0)
    MoveBase.publish_plan(mb, PATH)
    assert mb.built == 0 and mb.plan_pub.sent == [] and mb.last_path is PATH
    mb.plan_pub.connections = 1
    MoveBase.publish_plan(mb, PATH[:2])
    (msg,) = mb.plan_pub.sent
    assert msg.header.frame_id == "map"
    assert [(p.pose.position.x, p.pose.position.y) for p in msg.poses] == [(0.0, 0.0), (0.5, 0.1)]


def test_a_late_subscriber_gets_the_latest_plan():
    mb = move_base(0)
    listener = _PlanOnSubscribe(mb)
    listener.peer_subscribe("/robot_0/move_base/plan", None, None)
    assert mb.plan_pub.sent == []                    # no plan yet: nothing to send
    MoveBase.publish_plan(mb, PATH[:2])
    MoveBase.publish_plan(mb, PATH)                  # both made while no one listened
    assert mb.built == 0
    mb.plan_pub.connections = 1
    listener.peer_subscribe("/robot_0/move_base/plan", None, None)
    (msg,) = mb.plan_pub.sent
    assert len(msg.poses) == 3 and msg.poses[-1].pose.position.y == pytest.approx(0.3)


def fake_localization(tf_connections, pose_connections):
    fl = FakeLocalization.__new__(FakeLocalization)
    fl.global_frame, fl.odom_frame = "map", "robot_0/odom"
    fl.delta = (0.0, 0.0, 0.0)
    fl.odom = PoseHistory(horizon=5.0)
    fl.heard = []
    fl.pose_listeners = [lambda pose, stamp: fl.heard.append((pose, stamp))]
    fl.pose_pub = Pub(pose_connections)

    class Broadcaster:
        pub_tf = Pub(tf_connections)

        def sendTransform(self, t):
            self.pub_tf.publish(t)
    fl.tf = Broadcaster()
    return fl


def truth(stamp, x, y, yaw):
    msg = Odometry()
    msg.header.stamp = rospy.Time.from_sec(stamp)
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


@pytest.mark.parametrize("tf_conn, pose_conn", [(0, 0), (1, 0), (0, 1), (2, 3)])
def test_fake_localization_builds_what_is_listened_to(tf_conn, pose_conn):
    fl = fake_localization(tf_conn, pose_conn)
    fl.odom.add(10.0, (1.0, 2.0, 0.0))           # odometry drifted by (+1, +2)
    FakeLocalization.publish(fl, truth(10.0, 3.0, 4.0, 0.5))
    # the in-process listener (move_base) always gets the pose
    assert len(fl.heard) == 1 and fl.heard[0][1] == pytest.approx(10.0)
    assert fl.heard[0][0] == pytest.approx((3.0, 4.0, 0.5))
    assert len(fl.tf.pub_tf.sent) == (1 if tf_conn else 0)
    assert len(fl.pose_pub.sent) == (1 if pose_conn else 0)
    if tf_conn:
        (t,) = fl.tf.pub_tf.sent
        assert (t.header.frame_id, t.child_frame_id) == ("map", "robot_0/odom")
        # map->odom composed with odom (1, 2, 0) gives the ground truth (3, 4, 0.5)
        tx, ty = t.transform.translation.x, t.transform.translation.y
        yaw = 2 * math.atan2(t.transform.rotation.z, t.transform.rotation.w)
        c, s = math.cos(yaw), math.sin(yaw)
        assert (tx + c * 1.0 - s * 2.0, ty + s * 1.0 + c * 2.0) == pytest.approx((3.0, 4.0))
        assert yaw == pytest.approx(0.5)
    if pose_conn:
        (p,) = fl.pose_pub.sent
        assert isinstance(p, PoseWithCovarianceStamped) and p.header.frame_id == "map"
        assert (p.pose.pose.position.x, p.pose.pose.position.y) == pytest.approx((3.0, 4.0))


def odometry(stamp, x, y, yaw):
    """An odometry message (the same message type as the ground truth)."""
    return truth(stamp, x, y, yaw)


def test_fake_localization_waits_for_the_odometry_of_each_instant():
    """Ground truth of two steps before their odometry (two connections, under load): each
    correction is built from the odometry of its own stamp, in order, none from an older
    one."""
    fl = fake_localization(1, 0)
    fl.pending = collections.deque()
    fl.lock = threading.Lock()
    fl.on_odom(odometry(1.0, 0.0, 0.0, 0.0))
    fl.on_truth(truth(1.0, 5.0, 5.0, 0.0))
    fl.on_truth(truth(1.1, 5.1, 5.0, 0.0))        # odometry of 1.1 and 1.2 not here yet
    fl.on_truth(truth(1.2, 5.2, 5.0, 0.0))
    assert [t.header.stamp.to_sec() for t in fl.tf.pub_tf.sent] == [1.0]
    fl.on_odom(odometry(1.1, 0.11, 0.0, 0.0))      # odometry runs 10 % long
    fl.on_odom(odometry(1.2, 0.22, 0.0, 0.0))
    sent = fl.tf.pub_tf.sent
    assert [t.header.stamp.to_sec() for t in sent] == pytest.approx([1.0, 1.1, 1.2])
    for t, (tx, ox) in zip(sent, [(5.0, 0.0), (5.1, 0.11), (5.2, 0.22)]):
        # map->odom o odom == truth, exactly: x offset tx - ox
        assert t.transform.translation.x == pytest.approx(tx - ox)
    assert [s for _, s in fl.heard] == pytest.approx([1.0, 1.1, 1.2])


def test_fake_localization_drops_truth_whose_odometry_never_comes():
    fl = fake_localization(1, 0)
    fl.pending = collections.deque()
    fl.lock = threading.Lock()
    fl.on_odom(odometry(0.0, 0.0, 0.0, 0.0))
    for k in range(1, 80):                         # 7.9 s of ground truth, no odometry
        fl.on_truth(truth(0.1 * k, 1.0, 0.0, 0.0))
    assert not fl.tf.pub_tf.sent
    assert len(fl.pending) <= 51                   # what fits in the 5 s history
    fl.on_truth(truth(0.05, 1.0, 0.0, 0.0))        # time went backwards: a new run
    assert [m.header.stamp.to_sec() for m in fl.pending] == pytest.approx([0.05])
    fl.on_odom(odometry(0.05, 0.0, 0.0, 0.0))
    assert [t.header.stamp.to_sec() for t in fl.tf.pub_tf.sent] == pytest.approx([0.05])
