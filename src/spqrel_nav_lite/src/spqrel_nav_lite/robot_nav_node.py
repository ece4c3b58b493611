"""robot_nav (per robot): localisation and navigation of one robot in one process.

It runs the components of the separate nodes -- ``amcl`` or ``fake_localization``, and
``move_base`` -- with their topics, services, action and parameter names unchanged
(``<robot ns>/amcl/*`` or ``<robot ns>/fake_localization/*``, and ``<robot ns>/move_base/*``,
exactly where the standalone nodes would read them), so launch files and agents cannot tell
the difference. Sharing one process saves what separate processes cost in rospy:

- odometry and ``/clock`` are received once for both components;
- the localiser hands every pose to move_base directly (``amcl_pose`` is still published,
  latched, for everyone else);
- the map and its distance transform are loaded once.

Private parameters: ``~localization`` (``AMCL`` | ``fake_localization``, default ``AMCL``),
``~map_yaml`` (else ``/map`` or ``static_map``, as the standalone nodes).
"""
import rospy

from .ros_util import fatal, get_map
from .amcl_node import Amcl, log_update_times
from .fake_localization_node import FakeLocalization
from .move_base_node import MoveBase

MODES = ("AMCL", "fake_localization")


def main():
    rospy.init_node("robot_nav")
    mode = rospy.get_param("~localization", "AMCL")
    if mode not in MODES:
        fatal(f"parameter ~localization: '{mode}' is not one of {', '.join(MODES)}")
    omap = get_map("~")
    move_base = MoveBase(ns="move_base/", omap=omap, subscribe_pose=False)
    if mode == "AMCL":
        loc = Amcl(ns="amcl/", omap=omap, pose_listeners=[move_base.set_localisation])
    else:
        loc = FakeLocalization(ns="fake_localization/",
                               pose_listeners=[move_base.set_localisation])
    rospy.loginfo("robot_nav: %s + move_base in one process", mode)
    rospy.spin()
    if mode == "AMCL":
        log_update_times(loc)
