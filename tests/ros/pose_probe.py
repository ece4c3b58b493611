#!/usr/bin/python3
"""Print one robot's ground-truth pose from the simulator about once per sim second, as
``<sim time> <x> <y>`` lines, and ``go <sim time>`` once the monitor has set ``/go_time``
(tests/ros/test_scenarios_ros.py: a failed robot stays put).
Usage: pose_probe.py ROBOT_ID (ROS_MASTER_URI of the run in the environment)."""
import sys

import rospy
from nav_msgs.msg import Odometry


def main():
    robot = int(sys.argv[1])
    rospy.init_node(f"pose_probe_{robot}", anonymous=True, disable_signals=True)
    last = [-1.0]
    go = [None]

    def on_pose(msg):
        t = msg.header.stamp.to_sec()
        if t - last[0] >= 1.0:
            last[0] = t
            if go[0] is None and rospy.has_param("/go_time"):
                go[0] = float(rospy.get_param("/go_time"))
                print(f"go {go[0]:.3f}", flush=True)
            p = msg.pose.pose.position
            print(f"{t:.2f} {p.x:.4f} {p.y:.4f}", flush=True)
    rospy.Subscriber(f"/robot_{robot}/base_pose_ground_truth", Odometry, on_pose,
                     queue_size=10)
    rospy.spin()


if __name__ == "__main__":
    main()
