"""Helpers shared by the ROS nodes (imports rospy; the other modules do not)."""
import os
import signal
import sys
import threading

import numpy as np
import rospy
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import OccupancyGrid
from nav_msgs.srv import GetMap

from .errors import InputError
from .mapio import OccupancyMap, load_map

from .geometry import quaternion_from_yaw, yaw_from_quaternion


def fatal(message, code=2):
    """One-line error on stderr (and rosout), then exit non-zero."""
    name = rospy.get_name() if rospy.core.is_initialized() else os.path.basename(sys.argv[0])
    line = f"{name}: error: {' '.join(str(message).split())}"
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
    if rospy.core.is_initialized():
        rospy.signal_shutdown(line)
    os._exit(code)


def init_node_signal_safe(name, **kwargs):
    """``rospy.init_node(name, **kwargs)``, with SIGINT and SIGTERM ending the node as rospy's
    own handlers do (``rospy.signal_shutdown``), but from a helper thread.

    rospy's handlers call ``signal_shutdown`` in the main thread, wherever the signal
    interrupts it. If that is inside ``Publisher.publish`` on a queued connection
    (``QueuedConnection.write_data`` holds the connection's lock), closing the topics takes
    the same lock in the same thread and the node deadlocks; roslaunch then kills it with
    SIGKILL 15 s later, and what the node does at its end is lost. Seen in the abstract
    world, whose main thread publishes /clock at every step, when agents of another launch
    were still connected at its shutdown (about 1 run in 10). Here the handler only sets an
    event, and a daemon thread waiting on it calls ``signal_shutdown``: it then waits for
    the lock like any other thread. Unlike rospy's SIGINT handler, no KeyboardInterrupt is
    raised in the main thread: loops end on ``rospy.is_shutdown()``."""
    rospy.init_node(name, disable_signals=True, **kwargs)
    requested = threading.Event()
    received = []

    def on_signal(signum, _frame):
        received.append(signum)
        requested.set()

    def shut_down():
        requested.wait()
        rospy.signal_shutdown(f"signal-{received[0]}")

    threading.Thread(target=shut_down, name="signal-shutdown", daemon=True).start()
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)


def param_name(name, ns="~"):
    """How a parameter is shown in errors: ``~name`` for a node's own, ``ns/name`` otherwise."""
    return ("~" + name) if ns == "~" else ns + name


def param(name, default, kind=float, check=None, what=None, ns="~"):
    """Read a parameter, validate its type and range (bad -> fatal one-liner).

    ``ns`` is where it lives: ``"~"`` (the node's private namespace, the default) or a
    relative namespace such as ``"move_base/"`` when several components share one process
    (robot_nav) but keep the parameter names of their standalone nodes."""
    full = ns + name
    v = rospy.get_param(full, default)
    shown = param_name(name, ns)
    try:
        if kind is bool:
            if isinstance(v, str) and v.lower() in ("true", "false"):
                v = v.lower() == "true"
            elif not isinstance(v, (bool, int)):
                raise ValueError
            v = bool(v)
        elif kind in (float, int):
            if isinstance(v, bool):
                raise ValueError
            v = kind(v)
            if kind is int and float(rospy.get_param(full, default)) != v:
                raise ValueError
            if not np.isfinite(v):
                raise ValueError
        else:
            v = kind(v)
    except (TypeError, ValueError):
        fatal(f"parameter {shown}: expected {kind.__name__}, got {v!r}")
    if check is not None and not check(v):
        fatal(f"parameter {shown}: {v!r} is invalid ({what or 'out of range'})")
    return v


def namespace_prefix():
    """'robot_0/' for a node in /robot_0, '' in the global namespace."""
    ns = rospy.get_namespace().strip("/")
    return ns + "/" if ns else ""


def strip_slash(frame):
    return frame.lstrip("/")


def pose_of(msg_pose):
    """(x, y, yaw) of a geometry_msgs/Pose."""
    q = msg_pose.orientation
    return (msg_pose.position.x, msg_pose.position.y, yaw_from_quaternion(q.x, q.y, q.z, q.w))


def fill_pose(msg_pose, pose):
    msg_pose.position.x, msg_pose.position.y = pose[0], pose[1]
    msg_pose.position.z = 0.0
    q = quaternion_from_yaw(pose[2])
    msg_pose.orientation.x, msg_pose.orientation.y = q[0], q[1]
    msg_pose.orientation.z, msg_pose.orientation.w = q[2], q[3]
    return msg_pose


def transform_msg(pose, stamp, parent, child):
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y = pose[0], pose[1]
    q = quaternion_from_yaw(pose[2])
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = q
    return t


def grid_to_map(msg):
    """OccupancyMap from a nav_msgs/OccupancyGrid."""
    info = msg.info
    data = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
    data = np.where(data < 0, -1, np.where(data >= 65, 100, np.where(data <= 19, 0, -1)))
    yaw = yaw_from_quaternion(info.origin.orientation.x, info.origin.orientation.y,
                              info.origin.orientation.z, info.origin.orientation.w)
    return OccupancyMap(data.astype(np.int8), info.resolution,
                        (info.origin.position.x, info.origin.position.y, yaw))


def map_to_grid(omap, frame_id="map", stamp=None):
    msg = OccupancyGrid()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp if stamp is not None else rospy.Time(0)
    msg.info.map_load_time = msg.header.stamp
    msg.info.resolution = omap.resolution
    msg.info.width, msg.info.height = omap.width, omap.height
    fill_pose(msg.info.origin, omap.origin)
    msg.data = omap.data.ravel().tolist()
    return msg


def get_map(ns="~"):
    """The map for a per-robot node: from the yaml in ``~map_yaml`` if set, else the first
    message on ``~map_topic`` (default ``/map``), else the ``static_map`` service (``ns``: the
    parameters' namespace, see :func:`param`)."""
    yaml_path = rospy.get_param(ns + "map_yaml", "")
    if yaml_path:
        try:
            return load_map(yaml_path)
        except InputError as e:
            fatal(f"parameter {param_name('map_yaml', ns)}: {e}")
    topic = rospy.get_param(ns + "map_topic", "/map")
    service = rospy.get_param(ns + "map_service", "/static_map")
    wait = float(rospy.get_param(ns + "map_wait", 60.0))
    deadline = rospy.get_time() + wait
    while not rospy.is_shutdown():
        try:
            return grid_to_map(rospy.wait_for_message(topic, OccupancyGrid, timeout=2.0))
        except rospy.ROSException:
            pass
        try:
            rospy.wait_for_service(service, timeout=0.5)
            return grid_to_map(rospy.ServiceProxy(service, GetMap)().map)
        except (rospy.ROSException, rospy.ServiceException):
            pass
        if rospy.get_time() > deadline:
            fatal(f"no map on {topic} or {service} after {wait:.0f} s (set "
                  f"{param_name('map_yaml', ns)} or start map_server)")
    sys.exit(0)
