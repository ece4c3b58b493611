"""nav_host: the localiser + move_base of MANY robots in one process.

Each hosted robot keeps exactly the interface of a per-robot ``robot_nav`` (or of the separate
``amcl`` / ``fake_localization`` and ``move_base`` nodes): its topics (``/robot_i/cmd_vel``,
``amcl_pose``, ``particlecloud``, ``move_base/plan``, ...), the ``/robot_i/move_base`` action,
the ``/robot_i/move_base/clear_costmaps`` and ``/robot_i/global_localization`` services, its
frames (``robot_i/odom``, ``robot_i/base_link``) and its parameters, read where the standalone
nodes read them (``/robot_i/move_base/*``, ``/robot_i/amcl/*``). Only the node name behind them
differs. What the robots share (docs/navigation.md) is built once per process by
:class:`~spqrel_nav_lite.shared.SharedMaps`: the static map, its distance transform, the
likelihood fields and the planner's cost grid and graph, plus a navigation-function cache
bounded by ``~plan_cache_mb`` (a goal searched for one robot is free for the others).

Private parameters: ``~robots`` (robot namespaces, a list or a space-separated string, e.g.
``"robot_0 robot_1"``), ``~localization`` (``AMCL`` | ``fake_localization``, default
``AMCL``), ``~map_yaml`` (else ``/map`` or ``static_map``), ``~plan_cache_mb`` (default 128)
and ``~plan_cache_goals`` (default 0: the cache keeps at least that many navigation functions,
whatever ``~plan_cache_mb`` says; the runner sets the patrol graph's vertex count),
``~plan_store`` (default empty: none; a folder shared with other processes and runs, see
:mod:`~spqrel_nav_lite.plan_store`; the runner sets it), ``~plan_store_mb`` (its bound,
default 4096), ``~control_threads`` (default 1: the threads that run the control loops of
the hosted robots, each a :class:`~spqrel_nav_lite.control_loop.ControlLoop` for every K-th
robot; 0: actionlib's execute thread per robot, as in ``robot_nav``),
``~shared_receiver`` (default true: one :class:`~spqrel_nav_lite.shared_receiver.SharedReceiver`
thread receives the hosted robots' ``odom``, ``base_pose_ground_truth`` and ``base_scan``;
false: rospy's thread per connection), ``~receive_coalesce`` (default 0.001 wall s: that
thread's wait after the first message of a burst, before it reads all that has arrived; 0:
each message as it comes). The hosted robots' cmd_vel and actionlib's feedback, status and
result publishers write without a send queue (docs/navigation.md, "Threads").
"""
import functools
import re

import rospy

from .ros_util import fatal, get_map, param
from .amcl_node import Amcl, log_update_times
from .control_loop import ControlLoop
from .fake_localization_node import FakeLocalization
from .move_base_node import MoveBase
from .shared import SharedMaps
from .shared_receiver import SharedReceiver

MODES = ("AMCL", "fake_localization")
ROBOT_NS = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


def robot_namespaces(value):
    """List of robot namespaces from ``~robots`` (list or space-separated string); raises
    ValueError with the reason when empty, malformed or repeated."""
    items = value.split() if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)) or not items:
        raise ValueError(f"expected a non-empty list of robot namespaces, got {value!r}")
    out = []
    for item in items:
        name = str(item).strip("/")
        if not ROBOT_NS.match(name):
            raise ValueError(f"'{item}' is not a valid namespace")
        if name in out:
            raise ValueError(f"robot '{name}' is listed twice")
        out.append(name)
    return out


def share_status_timers(servers):
    """One thread publishes the periodic action status of all hosted robots.

    actionlib's ActionServer starts a ``rospy.Timer`` per server for its status (5 Hz by
    default, ``actionlib_status_frequency``); under simulated time every such timer thread
    wakes on every ``/clock`` message, so with many robots per process these wake-ups cost
    CPU of their own (docs/navigation.md, "Threads"). The servers' timers are
    stopped and one timer per status frequency publishes for all of them, with the same
    ``publish_status_async`` at the same rate, so the status topics are unchanged. Returns
    the new timers."""
    groups = {}
    for server in servers:
        timer = getattr(server, "status_timer", None)
        if timer is None:           # status_frequency 0: no periodic status
            continue
        timer.shutdown()
        groups.setdefault(server.status_frequency, []).append(server)

    def publish_all(event, group):
        for server in group:
            server.publish_status_async(event)
    return [rospy.Timer(rospy.Duration(1.0 / freq), functools.partial(publish_all, group=group))
            for freq, group in groups.items()]


def main():
    rospy.init_node("nav_host")
    mode = rospy.get_param("~localization", "AMCL")
    if mode not in MODES:
        fatal(f"parameter ~localization: '{mode}' is not one of {', '.join(MODES)}")
    try:
        robots = robot_namespaces(rospy.get_param("~robots", ""))
    except ValueError as e:
        fatal(f"parameter ~robots: {e}")
    cache_mb = param("plan_cache_mb", 128.0, check=lambda v: v >= 0, what="must be >= 0")
    cache_goals = param("plan_cache_goals", 0, int, check=lambda v: v >= 0, what="must be >= 0")
    store = param("plan_store", "", str) or None
    store_mb = param("plan_store_mb", 4096.0, check=lambda v: v >= 0, what="must be >= 0")
    threads = param("control_threads", 1, int, check=lambda v: v >= 0, what="must be >= 0")
    coalesce = param("receive_coalesce", 0.001, check=lambda v: v >= 0, what="must be >= 0")
    receiver = None
    if param("shared_receiver", True, bool):
        receiver = SharedReceiver(
            (rospy.resolve_name("/" + name + "/" + topic) for name in robots
             for topic in ("odom", "base_scan", "base_pose_ground_truth")),
            coalesce=coalesce).install()
    shared = SharedMaps(get_map("~"), cache_bytes=cache_mb * 2**20, cache_goals=cache_goals,
                        store_root=store, store_bytes=store_mb * 2**20)
    hosted = []
    loops = [ControlLoop() for _ in range(min(threads, len(robots)))]
    for k, name in enumerate(robots):
        r = "/" + name + "/"
        move_base = MoveBase(ns="move_base/", subscribe_pose=False, robot_ns=r, shared=shared,
                             control_loop=loops[k % len(loops)] if loops else None,
                             sync_publishers=True)
        if mode == "AMCL":
            loc = Amcl(ns="amcl/", pose_listeners=[move_base.set_localisation], robot_ns=r,
                       shared=shared)
        else:
            loc = FakeLocalization(ns="fake_localization/",
                                   pose_listeners=[move_base.set_localisation], robot_ns=r)
        hosted.append((move_base, loc))
    share_status_timers([mb.server.action_server for mb, _ in hosted])
    for loop in loops:
        loop.start()
    rospy.loginfo("nav_host: %s + move_base of %d robots (%s) in one process, %s", mode,
                  len(robots), " ".join(robots),
                  f"{len(loops)} control thread(s)" if loops else "a control thread per robot")
    rospy.spin()
    for loop in loops:
        rospy.loginfo("nav_host: control loop: %d passes over its %d robots, %d goal steps",
                      loop.wakeups, len(loop.nodes), loop.steps)
    if receiver is not None:
        rospy.loginfo("nav_host: one thread received %d messages of %d connections in %d "
                      "wake-ups", receiver.messages, receiver.connections, receiver.wakeups)
    fields, grids, cached, hits, misses, loads, saves = shared.stats()
    rospy.loginfo("nav_host: %d likelihood field(s), %d planner grid(s), %d navigation "
                  "functions cached, %d cache hits, %d misses, %d read from the plan store, "
                  "%d written to it", fields, grids, cached, hits, misses, loads, saves)
    if mode == "AMCL":
        for _, loc in hosted:
            log_update_times(loc)
