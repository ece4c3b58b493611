"""move_base (per robot): a move_base_msgs/MoveBaseAction server with a Dijkstra global
planner over the map's distance transform and a pure-pursuit local controller.

Pose input: odom + amcl_pose (from amcl or fake_localization), composed as
pose_map = amcl_pose o (odom_at_amcl_stamp^-1 o odom_now); no tf listener.
Interfaces: action move_base, topic move_base_simple/goal, service move_base/clear_costmaps,
outputs cmd_vel and ~plan (nav_msgs/Path); feedback carries the pose in the map frame.
"""
import functools
import math
import threading
import time

import actionlib
import numpy as np
import rospy
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist
from move_base_msgs.msg import (MoveBaseAction, MoveBaseFeedback, MoveBaseGoal,
                                MoveBaseResult)
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Empty, EmptyResponse

from spqrel_nav_lite.controller import ControllerParams, compute_command
from spqrel_nav_lite.geometry import PoseHistory, compose, inverse, relative
from spqrel_nav_lite.obstacles import ObstacleMemory, scan_points, to_world
from spqrel_nav_lite.particle_filter import LikelihoodField
from spqrel_nav_lite.planner import GlobalPlanner, PlanningError, path_blocked, path_length
from spqrel_nav_lite.ros_util import fill_pose, get_map, param, pose_of, strip_slash

POS = dict(check=lambda v: v > 0, what="must be positive")
NONNEG = dict(check=lambda v: v >= 0, what="must be >= 0")


class Aborted(Exception):
    pass


class MoveBase:
    """``ns``: parameter namespace (``"~"`` as a standalone node, ``"move_base/"`` inside
    robot_nav: the service and plan topic then live there too, as with the standalone node);
    ``omap``: the map if already loaded; ``subscribe_pose``: False when the localiser runs in
    the same process and calls :meth:`set_localisation` itself."""

    def __init__(self, ns="~", omap=None, subscribe_pose=True):
        self._p = functools.partial(param, ns=ns)
        self.global_frame = strip_slash(self._p("global_frame_id", "map", str))
        self.frequency = self._p("controller_frequency", 10.0, **POS)
        self.planner_frequency = self._p("planner_frequency", 1.0, **NONNEG)
        # the stock move_base publishes feedback once per control cycle, i.e. at the
        # original's controller_frequency of 5 Hz; agents publish /positions from it
        self.feedback_period = 1.0 / self._p("feedback_frequency", 5.0, **POS)
        self.max_recoveries = self._p("max_recoveries", 3, int, **NONNEG)
        self.goal_timeout = self._p("goal_timeout", 0.0, **NONNEG)
        self.controller_patience = self._p("controller_patience", 15.0, **POS)
        self.blocked_patience = self._p("blocked_patience", 2.0, **POS)
        self.obstacle_range = self._p("obstacle_range", 2.5, **POS)
        self.obstacle_timeout = self._p("obstacle_timeout", 3.0, **POS)
        self.unexplained_dist = self._p("unexplained_dist", 0.25, **POS)
        self.laser_x = self._p("laser_x", 0.15)
        self.localization_timeout = self._p("localization_timeout", 10.0, **POS)
        p = ControllerParams()
        for name in ("max_vel_x", "min_vel_x", "max_rot_vel", "min_in_place_rotational_vel",
                     "acc_lim_x", "acc_lim_th", "xy_goal_tolerance", "robot_radius"):
            setattr(p, name, self._p(name, getattr(p, name), **POS))
        self.cp = p
        omap = get_map(ns) if omap is None else omap
        t0 = time.time()
        self.planner = GlobalPlanner(omap, robot_radius=p.robot_radius,
                                     inflation_radius=self._p("inflation_radius", 0.66, **NONNEG),
                                     resolution=self._p("planner_resolution", 0.1, **POS),
                                     obstacle_margin=self._p("obstacle_margin", 0.2, **NONNEG),
                                     cache_bytes=self._p("plan_cache_mb", 32.0, **NONNEG) * 2**20)
        self.field = LikelihoodField(omap, max_dist=1.0)
        rospy.loginfo("move_base: planner grid %dx%d at %.3f m, built in %.2f s",
                      self.planner.w, self.planner.h, self.planner.res, time.time() - t0)
        self.memory = ObstacleMemory(cell=self.planner.res, timeout=self.obstacle_timeout)
        self.lock = threading.Lock()
        self.odom = PoseHistory(horizon=10.0)
        self.odom_cond = threading.Condition(self.lock)    # notified on every odometry
        self.loc = None          # (map pose, odom pose at its stamp)
        self.scan = None
        self.v = self.w = 0.0
        self.cmd_pub = rospy.Publisher("cmd_vel", Twist, queue_size=1)
        self.plan_pub = rospy.Publisher(ns + "plan", Path, queue_size=1, latch=True)
        rospy.Subscriber("odom", Odometry, self.on_odom, queue_size=5, tcp_nodelay=True)
        if subscribe_pose:
            rospy.Subscriber("amcl_pose", PoseWithCovarianceStamped, self.on_loc, queue_size=2,
                             tcp_nodelay=True)
        rospy.Subscriber("base_scan", LaserScan, self.on_scan, queue_size=1, tcp_nodelay=True,
                         buff_size=1 << 20)
        rospy.Service(ns + "clear_costmaps", Empty, self.on_clear)
        self.server = actionlib.SimpleActionServer("move_base", MoveBaseAction,
                                                   execute_cb=self.execute, auto_start=False)
        self.server.start()
        self.client = None
        rospy.Subscriber("move_base_simple/goal", PoseStamped, self.on_simple_goal, queue_size=1)
        self.plans = 0
        rospy.on_shutdown(self.log_statistics)

    def log_statistics(self):
        pl = self.planner
        rospy.loginfo("move_base: %d plans, %d Dijkstra searches (%d with obstacles in a window), "
                      "%d navigation functions cached", self.plans, pl.searches,
                      pl.window_searches, len(pl._cache))

    # -- inputs -----------------------------------------------------------------------------------
    def on_odom(self, msg):
        with self.lock:
            self.odom.add(msg.header.stamp.to_sec(), pose_of(msg.pose.pose))
            self.odom_cond.notify_all()

    def wait_cycle(self, period, used_stamp):
        """Wait for the next control cycle: the first odometry at least ~one period newer than
        ``used_stamp`` (the odometry the last command was computed from), so that every command
        is computed from a fresh pose right after the simulator's step and reaches it before
        the next one; waking on /clock instead would use the previous step's pose (one step
        more of latency). Falls back to the period in ROS time if odometry stops."""
        deadline = rospy.get_time() + 1.5 * period
        with self.odom_cond:
            while not rospy.is_shutdown():
                latest = self.odom.latest()
                if latest is not None and used_stamp is not None and \
                        latest[0] >= used_stamp + 0.75 * period:
                    return
                if rospy.get_time() >= deadline:
                    return
                self.odom_cond.wait(0.25)   # woken by every odometry message

    def odom_stamp(self):
        with self.lock:
            latest = self.odom.latest()
            return None if latest is None else latest[0]

    def on_loc(self, msg):
        self.set_localisation(pose_of(msg.pose.pose), msg.header.stamp.to_sec())

    def set_localisation(self, pose, stamp):
        """The localiser's map-frame pose at time ``stamp`` (s)."""
        with self.lock:
            # odometry at the localiser's stamp; if none has arrived yet (latched pose at
            # start-up), it is looked up when the pose is first needed
            self.loc = (pose, self.odom.at(stamp), stamp)

    def on_scan(self, msg):
        self.scan = msg

    def on_clear(self, _req):
        with self.lock:
            self.memory.clear()
        return EmptyResponse()

    def on_simple_goal(self, msg):
        if self.client is None:
            self.client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
            self.client.wait_for_server(rospy.Duration(5.0))
        self.client.send_goal(MoveBaseGoal(target_pose=msg))

    def pose(self):
        """Current pose in the map frame, or None."""
        with self.lock:
            if self.loc is None:
                return None
            latest = self.odom.latest()
            if latest is None:
                return None
            loc, odom_then, stamp = self.loc
            if odom_then is None:
                odom_then = self.odom.at(stamp)
                self.loc = (loc, odom_then, stamp)
            return compose(loc, relative(odom_then, latest[1]))

    # -- helpers -----------------------------------------------------------------------------------
    def send(self, v, w):
        self.v, self.w = v, w
        t = Twist()
        t.linear.x, t.angular.z = v, w
        self.cmd_pub.publish(t)

    def stop(self):
        self.send(0.0, 0.0)

    def laser(self, pose):
        """(points in the robot frame within 3 m, the unexplained ones among them in the
        robot frame)."""
        scan = self.scan
        if scan is None:
            return np.zeros((0, 2)), np.zeros((0, 2))
        step = max(1, int(round(math.radians(1.0) / max(abs(scan.angle_increment), 1e-6))))
        pts, r, _ = scan_points(scan.ranges, scan.angle_min, scan.angle_increment,
                                scan.range_min, scan.range_max, self.laser_x, step,
                                max_range=max(3.0, self.obstacle_range))
        near3 = r <= 3.0
        near = pts[near3]
        world = to_world(pts, pose)
        strange = self.field.lookup(world[:, 0], world[:, 1]) > self.unexplained_dist
        unexplained = world[strange & (r <= self.obstacle_range)]
        now = rospy.get_time()
        with self.lock:
            sensor = compose(pose, (self.laser_x, 0.0, 0.0))[:2]
            self.memory.clear_seen_through(sensor, world, now)
            self.memory.expire(now)
            self.memory.add(unexplained, now)
        return near, pts[near3 & strange]

    def publish_plan(self, path):
        msg = Path()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.global_frame
        for x, y in path:
            ps = PoseStamped()
            ps.header = msg.header
            ps.pose.position.x, ps.pose.position.y = float(x), float(y)
            ps.pose.orientation.w = 1.0
            msg.poses.append(ps)
        self.plan_pub.publish(msg)

    def make_plan(self, pose, goal, with_obstacles=True, refresh=True):
        """Plan from the navigation function. ``refresh``: first load the current temporary
        obstacles (a changed set costs a new Dijkstra run); without it the existing function
        is reused (periodic re-planning from the new position)."""
        if refresh:
            with self.lock:
                pts = self.memory.points() if with_obstacles else np.zeros((0, 2))
            self.planner.set_obstacles(pts)
        path = self.planner.plan(pose[:2], goal, tolerance=self.cp.xy_goal_tolerance)
        self.plans += 1
        self.publish_plan(path)
        return path

    # -- the action ----------------------------------------------------------------------------
    def execute(self, goal_msg):
        while True:
            try:
                nxt = self.run_goal(goal_msg)
            except Aborted as e:
                self.stop()
                rospy.logwarn("move_base: goal aborted: %s", e)
                self.server.set_aborted(MoveBaseResult(), str(e))
                return
            except rospy.ROSInterruptException:
                self.end_at_shutdown()
                return
            except Exception as e:     # never leave the robot driving on a bug
                self.stop()
                rospy.logerr("move_base: internal error: %r", e)
                self.server.set_aborted(MoveBaseResult(), f"internal error: {e!r}")
                return
            self.stop()
            if nxt is None:
                self.end_at_shutdown()
                return
            goal_msg = nxt

    def end_at_shutdown(self):
        """Every goal ends in a terminal state: the control loop also ends when the node shuts
        down (rospy.is_shutdown(), or a sleep raising ROSInterruptException) with the goal
        still active; it is then aborted, before actionlib would do it with a warning."""
        if not self.server.is_active():
            return
        try:
            self.server.set_aborted(MoveBaseResult(), "navigation shutting down")
        except Exception as e:  # the result publisher may already be closed: nothing to tell
            rospy.logdebug("move_base: aborting the goal at shutdown: %r", e)

    def run_goal(self, goal_msg):
        """Drive to the goal. Returns a new goal if preempted by one, None when finished."""
        frame = strip_slash(goal_msg.target_pose.header.frame_id)
        if frame not in ("", self.global_frame):
            raise Aborted(f"goal frame '{frame}' is not the global frame "
                          f"'{self.global_frame}'")
        gp = goal_msg.target_pose.pose.position
        goal = (gp.x, gp.y)
        if not (math.isfinite(gp.x) and math.isfinite(gp.y)):
            raise Aborted("goal position is not finite")
        rate = rospy.Rate(self.frequency)
        dt = 1.0 / self.frequency
        start = rospy.get_time()
        pose = self.pose()
        while pose is None:
            if rospy.get_time() - start > self.localization_timeout:
                raise Aborted(f"no pose: nothing on amcl_pose/odom for "
                              f"{self.localization_timeout:.0f} s")
            if self.server.is_preempt_requested():
                return self.preempted()
            rate.sleep()
            pose = self.pose()
        self.laser(pose)
        try:
            path = self.make_plan(pose, goal)
        except PlanningError as e:
            self.planner.clear_obstacles()
            try:    # a bad goal is final
                self.planner.check_goal(goal[0], goal[1], self.cp.xy_goal_tolerance)
            except PlanningError as bad:
                raise Aborted(str(bad)) from None
            try:    # maybe only temporary obstacles are in the way: try the static map
                with self.lock:
                    self.memory.clear()
                path = self.make_plan(pose, goal, with_obstacles=False)
            except PlanningError:
                raise Aborted(str(e)) from None
        timeout = self.goal_timeout if self.goal_timeout > 0 else \
            30.0 + 4.0 * path_length(path) / self.cp.max_vel_x
        deadline = start + timeout
        index = 0
        last_plan = rospy.get_time()
        best_remaining, best_time = math.inf, rospy.get_time()
        blocked_since = None
        recoveries = 0
        feedback = MoveBaseFeedback()
        feedback.base_position.header.frame_id = self.global_frame
        last_feedback = -math.inf
        while not rospy.is_shutdown():
            if self.server.is_preempt_requested():
                return self.preempted()
            now = rospy.get_time()
            if now > deadline:
                raise Aborted(f"timeout: goal not reached within {timeout:.0f} s")
            used_stamp = self.odom_stamp()
            pose = self.pose()
            if pose is None:
                raise Aborted("lost the pose")
            near, dynamic = self.laser(pose)
            # periodic replanning (the navigation function makes it cheap unless the
            # obstacle set changed), and immediate replanning if the path is blocked
            replan = self.planner_frequency > 0 and now - last_plan >= 1.0 / self.planner_frequency
            with self.lock:
                obst = self.memory.points()
            refresh = False
            if len(obst) and now - last_plan >= 0.5 and \
                    path_blocked(path, obst, self.cp.robot_radius + self.cp.safety_margin, index,
                                 3.0) is not None:
                replan = refresh = True
            if replan:
                last_plan = now
                try:
                    path = self.make_plan(pose, goal, refresh=refresh)
                    index = 0
                except PlanningError as e:
                    if blocked_since is None:
                        blocked_since = now
                    rospy.logdebug("move_base: replanning failed: %s", e)
            cmd = compute_command(pose, self.v, self.w, path, index, near, dt, self.cp, dynamic)
            index = cmd.index
            if cmd.done:
                self.stop()
                self.server.set_succeeded(MoveBaseResult(), "goal reached")
                return None
            remaining = self.planner.path_cost(pose[:2])
            if not math.isfinite(remaining):
                remaining = path_length(path[index:])
            if remaining < best_remaining - 0.1:
                best_remaining, best_time = remaining, now
            if cmd.blocked:
                blocked_since = blocked_since if blocked_since is not None else now
            elif self.v > 0.05:
                blocked_since = None
            stuck = (blocked_since is not None and now - blocked_since > self.blocked_patience) \
                or now - best_time > self.controller_patience
            if stuck:
                recoveries += 1
                reason = "blocked by an obstacle" if blocked_since is not None else \
                    f"no progress for {self.controller_patience:.0f} s"
                if recoveries > self.max_recoveries:
                    raise Aborted(f"{reason}; giving up after {self.max_recoveries} recoveries")
                rospy.loginfo("move_base: %s, recovery %d/%d", reason, recoveries,
                              self.max_recoveries)
                res = self.recover(recoveries, goal, rate)
                if res is not None:
                    return res
                pose = self.pose()
                try:
                    path = self.make_plan(pose, goal)
                except PlanningError:
                    pass
                index = 0
                blocked_since = None
                best_remaining, best_time = math.inf, rospy.get_time()
                last_plan = rospy.get_time()
                continue
            self.send(cmd.v, cmd.w)
            if now - last_feedback >= self.feedback_period - 1e-6:
                last_feedback = now
                feedback.base_position.header.stamp = rospy.Time.now()
                fill_pose(feedback.base_position.pose, pose)
                self.server.publish_feedback(feedback)
            self.wait_cycle(dt, used_stamp)
        return None

    def preempted(self):
        self.stop()
        if self.server.is_new_goal_available():
            return self.server.accept_new_goal()
        self.server.set_preempted(MoveBaseResult(), "preempted")
        return None

    def recover(self, attempt, goal, rate):
        """Back up a little if nothing is close beside or behind, then turn in place towards
        the freer side. Returns a new goal if preempted meanwhile."""
        pose0 = self.pose()
        t0 = rospy.get_time()
        # 1. back up 0.3 m (the laser does not see behind: only if the sides are clear)
        while rospy.get_time() - t0 < 3.0:
            if self.server.is_preempt_requested():
                return self.preempted()
            pose = self.pose()
            near, _ = self.laser(pose)
            if math.hypot(pose[0] - pose0[0], pose[1] - pose0[1]) > 0.3:
                break
            side = near[(near[:, 0] < 0.1)] if len(near) else near
            if len(side) and np.min(np.hypot(side[:, 0], side[:, 1])) < self.cp.robot_radius + 0.1:
                break
            if self.planner.map.clearance_at(*compose(pose, (-0.35, 0.0, 0.0))[:2]) < \
                    self.cp.robot_radius:
                break
            self.send(-0.15, 0.0)
            rate.sleep()
        self.stop()
        # 2. turn in place by up to ~1.5 rad, away from the nearest obstacle side
        pose = self.pose()
        near, _ = self.laser(pose)
        direction = 1.0 if attempt % 2 else -1.0
        if len(near):
            left = near[near[:, 1] > 0]
            right = near[near[:, 1] <= 0]
            dl = np.min(np.hypot(*left.T)) if len(left) else 99.0
            dr = np.min(np.hypot(*right.T)) if len(right) else 99.0
            direction = 1.0 if dl > dr else -1.0
        yaw0 = pose[2]
        t0 = rospy.get_time()
        while rospy.get_time() - t0 < 4.0:
            if self.server.is_preempt_requested():
                return self.preempted()
            pose = self.pose()
            turned = abs(math.atan2(math.sin(pose[2] - yaw0), math.cos(pose[2] - yaw0)))
            if turned > 1.5:
                break
            w = direction * 0.6
            self.send(0.0, w)
            self.laser(pose)
            rate.sleep()
        self.stop()
        # obstacles still seen stay in memory (so the new plan goes around them); the others
        # expire or are cleared by the beams that now pass through them
        return None


def main():
    rospy.init_node("move_base")
    MoveBase()
    rospy.spin()
