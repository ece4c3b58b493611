#!/usr/bin/python3
"""Print one robot's ground-truth pose from the simulator about once per sim second, as
``<sim time> <x> <y>`` lines, and ``go <sim time>`` once the monitor has set ``/go_time``
(tests/ros/test_scenarios_ros.py: a failed robot stays put).
Usage: pose_probe.py ROBOT_ID [TOPIC] (ROS_MASTER_URI of the run in the environment);
TOPIC defaults to the simulator's ``base_pose_ground_truth`` (the abstract world: ``odom``)."""
import sys

import rospy
from nav_msgs.msg import Odometry


def main():
    robot = int(sys.argv[1])
    topic = sys.argv[2] if len(sys.argv) > 2 else "base_pose_ground_truth"
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
    rospy.Subscriber(f"/robot_{robot}/{topic}", Odometry, on_pose,
                     queue_size=10)
    rospy.spin()


if __name__ == "__main__":
    main()
