#!/usr/bin/python3
"""Checks, on a running experiment's master, that every robot's navigation interface is the
per-robot one whatever process hosts it: topic names and types, the ``move_base`` action
(goal/cancel subscribed, status/feedback/result published, the agent's client connected),
``move_base/clear_costmaps`` (called, must answer), parameters where the standalone nodes read
them, and the tf frames ``map -> robot_i/odom``.

Usage (ROS_MASTER_URI of the run in the environment): nav_layout_check.py N LOCALIZATION
Prints ``OK <summary>`` and exits 0, or one line per problem and exits 1.
"""
import sys
import time

import rosgraph
import rospy
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

#: (topic relative to the robot namespace, type) published by the navigation
PUBLISHED = [("cmd_vel", "geometry_msgs/Twist"),
             ("amcl_pose", "geometry_msgs/PoseWithCovarianceStamped"),
             ("move_base/plan", "nav_msgs/Path"),
             ("move_base/status", "actionlib_msgs/GoalStatusArray"),
             ("move_base/feedback", "move_base_msgs/MoveBaseActionFeedback"),
             ("move_base/result", "move_base_msgs/MoveBaseActionResult")]
#: topics the navigation subscribes
SUBSCRIBED = ["odom", "base_scan", "move_base/goal", "move_base/cancel",
              "move_base_simple/goal"]
SUBSCRIBED_LOC = {"fake_localization": ["base_pose_ground_truth"],
                  "AMCL": ["initialpose"]}
PUBLISHED_LOC = {"AMCL": [("particlecloud", "geometry_msgs/PoseArray")],
                 "fake_localization": []}
SERVICES = {"fake_localization": ["move_base/clear_costmaps"],
            "AMCL": ["move_base/clear_costmaps", "global_localization"]}
PARAMS = {"fake_localization": ["fake_localization/odom_frame_id", "move_base/map_yaml"],
          "AMCL": ["amcl/odom_frame_id", "amcl/initial_pose_x", "move_base/map_yaml"]}


def main():
    n, loc = int(sys.argv[1]), sys.argv[2]
    rospy.init_node("nav_layout_check", anonymous=True, disable_signals=True)
    master = rosgraph.Master(rospy.get_name())
    pubs, subs, srvs = master.getSystemState()
    pubs, subs, srvs = dict(pubs), dict(subs), dict(srvs)
    types = dict(master.getTopicTypes())
    problems = []
    hosts = set()
    for i in range(n):
        r = f"/robot_{i}/"
        for topic, kind in PUBLISHED + PUBLISHED_LOC[loc]:
            nodes = pubs.get(r + topic, [])
            if not nodes:
                problems.append(f"nobody publishes {r + topic}")
            elif types.get(r + topic) != kind:
                problems.append(f"{r + topic} has type {types.get(r + topic)}, not {kind}")
            hosts.update(x for x in nodes if "nav_host" in x)
        for topic in SUBSCRIBED + SUBSCRIBED_LOC[loc]:
            if not any("nav_host" in x for x in subs.get(r + topic, [])):
                problems.append(f"no navigation node subscribes {r + topic}")
        # the robot's own agent process is the action client (one agent per process)
        agent = f"/patrol_robot{i}"
        if agent not in pubs.get(r + "move_base/goal", []) or \
                agent not in subs.get(r + "move_base/status", []):
            problems.append(f"{agent} is not a client of the {r}move_base action")
        for name in PARAMS[loc]:
            if not rospy.has_param(r + name):
                problems.append(f"parameter {r + name} not set")
        if rospy.get_param(r + PARAMS[loc][0], "") != f"robot_{i}/odom":
            problems.append(f"{r + PARAMS[loc][0]} is not robot_{i}/odom")
        for name in SERVICES[loc]:
            if r + name not in srvs:
                problems.append(f"service {r + name} missing")
        try:
            rospy.ServiceProxy(r + "move_base/clear_costmaps", Empty)()
        except (rospy.ServiceException, rospy.ROSException) as e:
            problems.append(f"{r}move_base/clear_costmaps failed: {e}")
    # frames: map -> robot_i/odom for every robot, from the localiser
    frames = set()

    def on_tf(msg):
        for t in msg.transforms:
            frames.add((t.header.frame_id.lstrip("/"), t.child_frame_id.lstrip("/")))
    sub = rospy.Subscriber("/tf", TFMessage, on_tf, queue_size=200)
    want = {("map", f"robot_{i}/odom") for i in range(n)}
    deadline = time.time() + 20.0
    while time.time() < deadline and not want <= frames:
        time.sleep(0.1)
    sub.unregister()
    for parent, child in sorted(want - frames):
        problems.append(f"no tf {parent} -> {child} seen")
    if problems:
        print("\n".join(problems))
        sys.exit(1)
    print(f"OK {n} robots served by {len(hosts)} nav_host process(es): {' '.join(sorted(hosts))}")


if __name__ == "__main__":
    main()
