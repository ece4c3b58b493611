"""amcl (per robot): Monte-Carlo localisation with amcl's parameter names.

Inputs: base_scan (sensor_msgs/LaserScan), odom (nav_msgs/Odometry; no tf listener), the map
(~map_yaml, /map or static_map), initialpose. Outputs: tf map->odom, amcl_pose,
particlecloud; service global_localization (std_srvs/Empty).
"""
import functools
import math
import threading
import time

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import Pose, PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rospy.numpy_msg import numpy_msg
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Empty, EmptyResponse

from spqrel_nav_lite.geometry import PoseHistory, compose, inverse, normalize_angle
from spqrel_nav_lite.particle_filter import LikelihoodField, ParticleFilter
from spqrel_nav_lite.ros_util import (fill_pose, get_map, namespace_prefix, param, pose_of,
                                      strip_slash, transform_msg)

# scans deserialised straight into numpy arrays (ranges: float32 ndarray, no tuple of floats)
SCAN = numpy_msg(LaserScan)
POS = dict(check=lambda v: v > 0, what="must be positive")
NONNEG = dict(check=lambda v: v >= 0, what="must be >= 0")


class Amcl:
    """``ns``: parameter namespace (``"~"`` as a standalone node, ``"amcl/"`` inside
    robot_nav); ``omap``: the map if already loaded. ``pose_listeners``: callables
    ``f(pose, stamp_sec)`` that receive every estimate in-process (robot_nav hands it to
    move_base this way). ``robot_ns`` (``"/robot_3/"`` in nav_host): prefix of every topic,
    service and parameter name, and the robot's frames' prefix; ``shared``: the process's
    :class:`~spqrel_nav_lite.shared.SharedMaps` (map and likelihood field built once)."""

    def __init__(self, ns="~", omap=None, pose_listeners=(), robot_ns="", shared=None):
        if robot_ns:
            ns = robot_ns + ns
        self._p = functools.partial(param, ns=ns)
        self.pose_listeners = list(pose_listeners)
        ns_param = ns
        self.robot_ns = r = robot_ns       # prefix of this robot's log lines in a nav_host
        ns = robot_ns.strip("/") + "/" if robot_ns.strip("/") else namespace_prefix()
        self.global_frame = strip_slash(self._p("global_frame_id", "map", str))
        self.odom_frame = strip_slash(self._p("odom_frame_id", ns + "odom", str))
        self.base_frame = strip_slash(self._p("base_frame_id", ns + "base_link", str))
        min_p = self._p("min_particles", 100, int, **POS)
        max_p = self._p("max_particles", 500, int, check=lambda v: v >= min_p,
                        what="must be >= ~min_particles")
        alphas = tuple(self._p(f"odom_alpha{i}", d, **NONNEG)
                       for i, d in zip(range(1, 5), (0.2, 0.2, 0.8, 0.2)))
        self.max_beams = self._p("laser_max_beams", 30, int, check=lambda v: v >= 2,
                                 what="must be >= 2")
        self.update_min_d = self._p("update_min_d", 0.2, **NONNEG)
        self.update_min_a = self._p("update_min_a", 0.5, **NONNEG)
        self.resample_interval = self._p("resample_interval", 1, int, **POS)
        self.transform_tolerance = self._p("transform_tolerance", 0.2, **NONNEG)
        self.laser_max_range = self._p("laser_max_range", -1.0)
        self.laser_min_range = self._p("laser_min_range", -1.0)
        self.tf_broadcast = self._p("tf_broadcast", True, bool)
        seed = self._p("seed", -1, int)
        if shared is not None:
            omap = shared.map
        omap = get_map(ns_param) if omap is None else omap
        t0 = time.time()
        max_dist = self._p("laser_likelihood_max_dist", 2.0, **POS)
        self.field = shared.likelihood_field(max_dist) if shared is not None else \
            LikelihoodField(omap, max_dist)
        self.pf = ParticleFilter(
            self.field, min_p, max_p, alphas,
            z_hit=self._p("laser_z_hit", 0.5, **NONNEG),
            z_rand=self._p("laser_z_rand", 0.5, **NONNEG),
            sigma_hit=self._p("laser_sigma_hit", 0.2, **POS),
            kld_err=self._p("kld_err", 0.05, **POS), kld_z=self._p("kld_z", 0.99, **POS),
            laser_x=self._p("laser_x", 0.15),
            model=self._p("odom_model_type", "diff", str,
                          check=lambda v: v in ("diff", "diff-corrected"),
                          what="must be diff or diff-corrected"),
            rng=np.random.default_rng(None if seed < 0 else seed))
        rospy.loginfo("amcl: likelihood field %dx%d in %.2f s", self.field.w, self.field.h,
                      time.time() - t0)
        init = (self._p("initial_pose_x", 0.0), self._p("initial_pose_y", 0.0),
                self._p("initial_pose_a", 0.0))
        self.pf.init_gaussian(init, self._p("initial_cov_xx", 0.5 * 0.5, **NONNEG),
                              self._p("initial_cov_yy", 0.5 * 0.5, **NONNEG),
                              self._p("initial_cov_aa", (math.pi / 12) ** 2, **NONNEG))
        self.lock = threading.Lock()
        self.odom = PoseHistory(horizon=5.0)
        self.last_update_odom = None     # odom pose at the last filter update
        self.force_update = True
        self.updates = 0
        self.correction = None           # map -> odom
        self.update_times = []
        self.tf = tf2_ros.TransformBroadcaster()
        self.pose_pub = rospy.Publisher(r + "amcl_pose", PoseWithCovarianceStamped,
                                        queue_size=2, latch=True)
        self.cloud_pub = rospy.Publisher(r + "particlecloud", PoseArray, queue_size=2,
                                         latch=True)
        rospy.Service(r + "global_localization", Empty, self.on_global)
        rospy.Subscriber(r + "initialpose", PoseWithCovarianceStamped, self.on_initialpose,
                         queue_size=1)
        rospy.Subscriber(r + "odom", Odometry, self.on_odom, queue_size=5, tcp_nodelay=True)
        rospy.Subscriber(r + "base_scan", SCAN, self.on_scan, queue_size=1,
                         tcp_nodelay=True, buff_size=1 << 20)

    # -- inputs --------------------------------------------------------------------------------
    def on_odom(self, msg):
        with self.lock:
            self.odom.add(msg.header.stamp.to_sec(), pose_of(msg.pose.pose))

    def on_initialpose(self, msg):
        p = pose_of(msg.pose.pose)
        c = msg.pose.covariance
        with self.lock:
            self.pf.init_gaussian(p, c[0] if c[0] > 0 else 0.25, c[7] if c[7] > 0 else 0.25,
                                  c[35] if c[35] > 0 else (math.pi / 12) ** 2)
            self.force_update = True
        rospy.loginfo("%samcl: initial pose set to (%.2f, %.2f, %.2f)", self.robot_ns, *p)

    def on_global(self, _req):
        with self.lock:
            self.pf.init_uniform()
            self.force_update = True
        rospy.loginfo("%samcl: global localisation, %d particles", self.robot_ns,
                      len(self.pf.particles))
        return EmptyResponse()

    def on_scan(self, msg):
        with self.lock:
            self._on_scan(msg)

    def _on_scan(self, msg):
        stamp = msg.header.stamp
        odom = self.odom.at(stamp.to_sec())
        if odom is None:
            return
        moved = False
        if self.last_update_odom is not None:
            d = math.hypot(odom[0] - self.last_update_odom[0], odom[1] - self.last_update_odom[1])
            a = abs(normalize_angle(odom[2] - self.last_update_odom[2]))
            moved = d >= self.update_min_d or a >= self.update_min_a
        if moved or self.force_update or self.last_update_odom is None:
            t0 = time.perf_counter()
            if self.last_update_odom is not None:
                self.pf.predict(self.last_update_odom, odom)
            self.last_update_odom = odom
            self.force_update = False
            n = len(msg.ranges)
            step = max(1, int(math.ceil((n - 1) / float(self.max_beams - 1)))) if n > 1 else 1
            idx = np.arange(0, n, step)[:self.max_beams]
            ranges = np.asarray(msg.ranges, dtype=float)[idx]
            angles = msg.angle_min + msg.angle_increment * idx
            rmax = self.laser_max_range if self.laser_max_range > 0 else msg.range_max
            rmin = self.laser_min_range if self.laser_min_range > 0 else msg.range_min
            ranges = np.where(ranges < rmin, np.inf, ranges)
            self.pf.laser_max_range = rmax
            self.pf.update(ranges, angles)
            self.updates += 1
            if self.updates % self.resample_interval == 0:
                est, cov = self.pf.estimate()
                self.pf.resample()
            else:
                est, cov = self.pf.estimate()
            self.update_times.append(time.perf_counter() - t0)
            self.correction = compose(est, inverse(odom))
            self.publish_pose(est, cov, stamp)
        # /tf is not latched: nothing to build when no one subscribes (fake_localization too)
        if self.correction is not None and self.tf_broadcast and \
                self.tf.pub_tf.get_num_connections():
            self.tf.sendTransform(transform_msg(
                self.correction, stamp + rospy.Duration(self.transform_tolerance),
                self.global_frame, self.odom_frame))

    def publish_pose(self, est, cov, stamp):
        out = PoseWithCovarianceStamped()
        out.header.stamp = stamp
        out.header.frame_id = self.global_frame
        fill_pose(out.pose.pose, est)
        c = [0.0] * 36
        c[0], c[1], c[6], c[7] = cov[0, 0], cov[0, 1], cov[1, 0], cov[1, 1]
        c[35] = cov[2, 2]
        out.pose.covariance = c
        self.pose_pub.publish(out)
        for f in self.pose_listeners:
            f(tuple(est), stamp.to_sec())
        if self.cloud_pub.get_num_connections():
            cloud = PoseArray()
            cloud.header = out.header
            cloud.poses = [fill_pose(Pose(), tuple(p)) for p in self.pf.particles]
            self.cloud_pub.publish(cloud)


def log_update_times(node):
    if node.update_times:
        t = np.array(node.update_times) * 1e3
        rospy.loginfo("%samcl: %d updates, median %.2f ms, p95 %.2f ms", node.robot_ns, len(t),
                      np.median(t), np.percentile(t, 95))


def main():
    rospy.init_node("amcl")
    node = Amcl()
    rospy.spin()
    log_update_times(node)
