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
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import Odometry, Path
from rospy.numpy_msg import numpy_msg
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Empty, EmptyResponse

from spqrel_nav_lite.controller import ControllerParams
from spqrel_nav_lite.geometry import PoseHistory, compose, relative
from spqrel_nav_lite.move_base_goal import GoalExecution
from spqrel_nav_lite.obstacles import ObstacleMemory, scan_points, to_frame, to_world
from spqrel_nav_lite.particle_filter import LikelihoodField
from spqrel_nav_lite.planner import OBSTACLE_SEARCHES, GlobalPlanner
from spqrel_nav_lite.planner_grid import PlannerGrid
from spqrel_nav_lite.ros_util import get_map, param, pose_of, strip_slash

# scans deserialised straight into numpy arrays (ranges: float32 ndarray, no tuple of floats)
SCAN = numpy_msg(LaserScan)
POS = dict(check=lambda v: v > 0, what="must be positive")
NONNEG = dict(check=lambda v: v >= 0, what="must be >= 0")


class MoveBase(GoalExecution):
    """``ns``: parameter namespace (``"~"`` as a standalone node, ``"move_base/"`` inside
    robot_nav: the service and plan topic then live there too, as with the standalone node);
    ``omap``: the map if already loaded; ``subscribe_pose``: False when the localiser runs in
    the same process and calls :meth:`set_localisation` itself. ``robot_ns``: prefix of every
    topic, service, action and parameter name (``"/robot_3/"`` in nav_host, which hosts many
    robots in one node; ``""``: the node's own namespace); ``shared``: a
    :class:`~spqrel_nav_lite.shared.SharedMaps` of the process (grid, fields and plan cache
    shared with its other robots); ``control_loop``: a
    :class:`~spqrel_nav_lite.control_loop.ControlLoop` that runs this robot's goals in the
    thread it shares with the process's other robots (None: actionlib's execute thread of
    this robot runs them); ``sync_publishers``: cmd_vel and the action's feedback, status and
    result written without a send queue (:func:`write_synchronously`)."""

    def __init__(self, ns="~", omap=None, subscribe_pose=True, robot_ns="", shared=None,
                 control_loop=None, sync_publishers=False):
        if robot_ns:
            ns = robot_ns + ns
        self._p = functools.partial(param, ns=ns)
        self._read_parameters()
        self._build_planner(ns, omap, shared)
        self.memory = ObstacleMemory(cell=self.planner.res, timeout=self.obstacle_timeout)
        self.lock = threading.Lock()
        self.odom = PoseHistory(horizon=10.0)
        self.odom_cond = threading.Condition(self.lock)    # notified on every odometry
        self.loc = None          # (map pose, odom pose at its stamp)
        self.scan = None
        self.v = self.w = 0.0
        self.robot_ns = robot_ns
        self._connect(ns, subscribe_pose, control_loop, sync_publishers)
        self.plans = 0
        rospy.on_shutdown(self.log_statistics)

    def _read_parameters(self):
        """Read the goal execution's and the controller's parameters (``self._p``) into
        attributes (``cp``: the :class:`ControllerParams`); a bad value is fatal
        (:func:`~spqrel_nav_lite.ros_util.param`)."""
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

    def _build_planner(self, ns, omap, shared):
        """Set ``planner`` (a :class:`GlobalPlanner`) and ``field`` (the likelihood field that
        tells the laser points the map explains): on the grid and field of ``shared`` (a
        :class:`~spqrel_nav_lite.shared.SharedMaps`) if given, else built here on ``omap``
        (read from the map server or ``ns``'s parameters if None) with this robot's plan
        store; logs the grid and its build time."""
        p = self.cp
        if shared is not None:
            omap = shared.map
        omap = get_map(ns) if omap is None else omap
        t0 = time.time()
        grid_args = dict(robot_radius=p.robot_radius,
                         inflation_radius=self._p("inflation_radius", 0.66, **NONNEG),
                         resolution=self._p("planner_resolution", 0.1, **POS),
                         cache_bytes=self._p("plan_cache_mb", 32.0, **NONNEG) * 2**20)
        margin = self._p("obstacle_margin", 0.2, **NONNEG)
        search = self._p("obstacle_search", "astar", str, lambda v: v in OBSTACLE_SEARCHES,
                         "one of " + ", ".join(OBSTACLE_SEARCHES))
        if shared is not None:
            self.planner = GlobalPlanner(omap, obstacle_margin=margin, obstacle_search=search,
                                         grid=shared.planner_grid(**grid_args))
            self.field = shared.likelihood_field(1.0)
        else:
            # the plan store (spqrel_nav_lite.plan_store): navigation functions computed by
            # any process on this grid before; a nav_host reads its own ~plan_store instead
            grid = PlannerGrid(omap, store_root=self._p("plan_store", "", str) or None,
                               store_bytes=self._p("plan_store_mb", 4096.0, **NONNEG) * 2**20,
                               **grid_args)
            self.planner = GlobalPlanner(omap, obstacle_margin=margin, obstacle_search=search,
                                         grid=grid)
            self.field = LikelihoodField(omap, max_dist=1.0)
        rospy.loginfo("move_base: planner grid %dx%d at %.3f m, built in %.2f s; searches with "
                      "obstacles: %s", self.planner.w, self.planner.h, self.planner.res,
                      time.time() - t0, self.planner.search_label)

    def _connect(self, ns, subscribe_pose, control_loop, sync_publishers):
        """Create the publishers, subscriptions, service and action server (under
        ``robot_ns``; the plan topic and the service under ``ns``) and start the server; with
        a ``control_loop`` it runs the goals, else actionlib's execute thread does."""
        r = self.robot_ns
        self.cmd_pub = rospy.Publisher(r + "cmd_vel", Twist, queue_size=1)
        if sync_publishers:         # before the simulator subscribes
            write_synchronously(self.cmd_pub)
        self.last_path = None
        self.plan_pub = rospy.Publisher(ns + "plan", Path, queue_size=1, latch=True,
                                        subscriber_listener=_PlanOnSubscribe(self))
        # set before the first subscription: a callback (on_odom) may run before __init__
        # returns
        self.control_loop = control_loop
        rospy.Subscriber(r + "odom", Odometry, self.on_odom, queue_size=5, tcp_nodelay=True)
        if subscribe_pose:
            rospy.Subscriber(r + "amcl_pose", PoseWithCovarianceStamped, self.on_loc,
                             queue_size=2, tcp_nodelay=True)
        rospy.Subscriber(r + "base_scan", SCAN, self.on_scan, queue_size=1,
                         tcp_nodelay=True, buff_size=1 << 20)
        rospy.Service(ns + "clear_costmaps", Empty, self.on_clear)
        self.server = actionlib.SimpleActionServer(
            r + "move_base", MoveBaseAction, auto_start=False,
            execute_cb=self.execute if control_loop is None else None)
        if control_loop is not None:
            self.server.register_goal_callback(control_loop.wake)
            control_loop.add(self)
        self.server.start()
        if sync_publishers:
            action = self.server.action_server
            for pub in (action.feedback_pub, action.status_pub, action.result_pub):
                write_synchronously(pub)
        self.client = None
        rospy.Subscriber(r + "move_base_simple/goal", PoseStamped, self.on_simple_goal,
                         queue_size=1)

    def log_statistics(self):
        pl = self.planner
        rospy.loginfo("%smove_base: %d plans, %d searches (%d with obstacles in a window, %d "
                      "A* expanding %d cells), %d navigation functions cached", self.robot_ns,
                      self.plans, pl.searches, pl.window_searches, pl.astar_searches,
                      pl.astar_expanded, len(pl.grid.cache))

    # -- inputs -----------------------------------------------------------------------------------
    def on_odom(self, msg):
        with self.lock:
            self.odom.add(msg.header.stamp.to_sec(), pose_of(msg.pose.pose))
            self.odom_cond.notify_all()
        if self.control_loop is not None:
            self.control_loop.wake()

    def cycle_due(self, period, used_stamp):
        """True when odometry at least ~one ``period`` newer than ``used_stamp`` (the odometry
        the last command was computed from) has arrived."""
        with self.lock:
            return self._cycle_due(period, used_stamp)

    def _cycle_due(self, period, used_stamp):
        latest = self.odom.latest()
        return latest is not None and used_stamp is not None and \
            latest[0] >= used_stamp + 0.75 * period

    def wait_cycle(self, period, used_stamp, deadline):
        """Wait for the next control cycle (:meth:`cycle_due`), so that every command is
        computed from a fresh pose right after the simulator's step and reaches it before the
        next one; waking on /clock instead would use the previous step's pose (one step more
        of latency). Falls back to ``deadline`` in ROS time if odometry stops."""
        with self.odom_cond:
            while not rospy.is_shutdown():
                if self._cycle_due(period, used_stamp):
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
            self.client = actionlib.SimpleActionClient(self.robot_ns + "move_base",
                                                       MoveBaseAction)
            self.client.wait_for_server(rospy.Duration(5.0))
        self.client.send_goal(MoveBaseGoal(target_pose=msg))

    def pose(self):
        """Current pose in the map frame, or None."""
        return self.pose_at(None)

    def pose_at(self, stamp):
        """Map pose at ROS time ``stamp`` (s; None: the latest odometry's time): the
        localisation composed with the odometry then (interpolated, clamped to the odometry
        kept), or None."""
        with self.lock:
            if self.loc is None:
                return None
            latest = self.odom.latest()
            if latest is None:
                return None
            loc, odom_then, loc_stamp = self.loc
            if odom_then is None:
                odom_then = self.odom.at(loc_stamp)
                self.loc = (loc, odom_then, loc_stamp)
            odom = latest[1] if stamp is None else self.odom.at(stamp)
            return compose(loc, relative(odom_then, odom))

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
        robot frame), from the latest scan; ``pose`` is the robot's map pose now.

        The scan is placed in the map with the robot's pose at the scan's stamp
        (:meth:`pose_at`), as a costmap looks up tf at the scan's time, and its points are
        then seen from ``pose``. The control cycle starts on odometry, and the scan of the
        same simulator step often arrives a moment later (on its own connection), so the
        cycle usually has the scan of the step before: placed with the current pose it was
        turned by the robot's rotation over that step (0.1 rad at 1 rad/s puts a wall 2.5 m
        away 0.25 m off, the ``unexplained_dist``), and walls became temporary obstacles
        (docs/navigation.md, "Scans at their own time")."""
        scan = self.scan
        if scan is None:
            return np.zeros((0, 2)), np.zeros((0, 2))
        step = max(1, int(round(math.radians(1.0) / max(abs(scan.angle_increment), 1e-6))))
        pts, r, _ = scan_points(scan.ranges, scan.angle_min, scan.angle_increment,
                                scan.range_min, scan.range_max, self.laser_x, step,
                                max_range=max(3.0, self.obstacle_range))
        seen_from = self.pose_at(scan.header.stamp.to_sec()) or pose
        world = to_world(pts, seen_from)
        if seen_from != pose:
            pts = to_frame(world, pose)
        near3 = r <= 3.0
        near = pts[near3]
        strange = self.field.lookup(world[:, 0], world[:, 1]) > self.unexplained_dist
        unexplained = world[strange & (r <= self.obstacle_range)]
        now = rospy.get_time()
        with self.lock:
            sensor = compose(seen_from, (self.laser_x, 0.0, 0.0))[:2]
            self.memory.clear_seen_through(sensor, world, now)
            self.memory.expire(now)
            self.memory.add(unexplained, now)
        return near, pts[near3 & strange]

    def publish_plan(self, path):
        """``path`` on ``~plan`` (latched), built only while someone subscribes: a Path of a
        few hundred PoseStamped costs milliseconds to build, and in a run usually no one
        listens (rviz does). A subscriber that comes later gets the latest plan at once
        (:class:`_PlanOnSubscribe`), as the latch would have given it."""
        self.last_path = path
        if self.plan_pub.get_num_connections():
            self.plan_pub.publish(self.plan_msg(path))

    def plan_msg(self, path):
        msg = Path()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.global_frame
        for x, y in path:
            ps = PoseStamped()
            ps.header = msg.header
            ps.pose.position.x, ps.pose.position.y = float(x), float(y)
            ps.pose.orientation.w = 1.0
            msg.poses.append(ps)
        return msg

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


def write_synchronously(publisher):
    """Make ``publisher`` write in the publishing thread (rospy's ``queue_size=None``) for the
    subscriber connections made from now on (those already made keep their queue), so call
    it before anyone subscribes. With a queue, rospy hands every message to a thread of its
    own per subscriber connection, which wakes to write it, and the queued write ends with
    ``time.sleep(0)``, handing the GIL to another thread: for cmd_vel, published every
    control cycle, and the action's feedback (``~feedback_frequency``), that is thread
    switches per message and per robot (docs/navigation.md, "Threads"). These messages are
    small and their subscribers read at once, so the write does not block; a subscriber that
    stopped reading would block it once the socket's buffer is full, so only nav_host, a
    simulation layout, uses it: the per-robot nodes keep a queue, as real robots need."""
    publisher.impl.set_queue_size(None)


class _PlanOnSubscribe(rospy.SubscribeListener):
    """A new subscriber of ``~plan`` gets the latest plan (plans made while no one listened
    were not built). rospy calls this from its connection thread before it sends the latched
    message, and not under the publisher's lock, so publishing here is safe: the new
    subscriber may get the plan twice, never an outdated one after it."""

    def __init__(self, move_base):
        super().__init__()
        self.move_base = move_base

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        path = self.move_base.last_path
        if path is not None:
            self.move_base.plan_pub.publish(self.move_base.plan_msg(path))


def main():
    rospy.init_node("move_base")
    MoveBase()
    rospy.spin()
