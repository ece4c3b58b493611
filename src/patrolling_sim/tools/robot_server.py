"""One robot of the abstract world: its move_base action server, clear_costmaps service and
odometry (used by abstract_world.py, docs/abstract_world.md)."""
import math
import time


class RobotServer:
    """ROS interface of one robot: action server, clear_costmaps, odometry."""

    def __init__(self, node, i):
        import actionlib
        import rospy
        from move_base_msgs.msg import MoveBaseAction
        from nav_msgs.msg import Odometry
        from std_srvs.srv import Empty, EmptyResponse
        self.node, self.i = node, i
        self.gh = None                  # the goal being executed (owned under node.lock)
        self.goals = self.succeeded = self.preempted = 0
        self.done_at = None             # sim time of the last SUCCEEDED
        self.hold_since = None          # wall time the clock started waiting for this robot
        self.released = False           # waited long enough: no more holds until next goal
        self.turnaround = []            # sim s from a SUCCEEDED to the next goal
        ns = f"robot_{i}"
        self.odom_pub = rospy.Publisher(f"{ns}/odom", Odometry, queue_size=1)
        self.odom = Odometry()
        self.odom.header.frame_id = f"{ns}/odom"
        self.odom.child_frame_id = f"{ns}/base_link"
        self.server = actionlib.ActionServer(f"{ns}/move_base", MoveBaseAction, self.on_goal,
                                             self.on_cancel, auto_start=False)
        self.srv = rospy.Service(f"{ns}/move_base/clear_costmaps", Empty,
                                 lambda _req: EmptyResponse())

    def on_goal(self, gh):
        # called with the action server's lock held; takes node.lock after it (the stepping
        # thread never holds node.lock while calling into a goal handle)
        p = gh.get_goal().target_pose.pose.position
        with self.node.lock:
            old, self.gh = self.gh, gh
            gh.set_accepted()
            start = 0.0                 # a reaction takes hold_after sim s, never less
            if self.done_at is not None:
                self.turnaround.append(self.node.world.time - self.done_at)
                start, self.done_at = self.done_at + self.node.hold_after, None
            self.node.world.set_goal(self.i, p.x, p.y, start)
            self.goals += 1
            self.hold_since, self.released = None, False
            self.node.message_hold.note(time.monotonic())
            self.node.traffic.notify_all()
            if old is not None:
                self.preempted += 1
        if old is not None:
            old.set_canceled(text="preempted by a new goal")

    def on_cancel(self, gh):
        with self.node.lock:
            if self.gh is None or gh != self.gh:
                return
            self.gh = None
            self.node.world.stop(self.i)
            self.preempted += 1
            self.node.message_hold.note(time.monotonic())
            self.node.traffic.notify_all()
        gh.set_canceled(text="cancelled: robot stopped")

    def fill_odom(self, stamp, world):
        o = self.odom
        o.header.stamp = stamp
        x, y = world.pos[self.i]
        yaw = world.yaw[self.i]
        o.pose.pose.position.x, o.pose.pose.position.y = x, y
        o.pose.pose.orientation.z = math.sin(yaw / 2)
        o.pose.pose.orientation.w = math.cos(yaw / 2)
        o.twist.twist.linear.x = world.speed if world.moving(self.i) else 0.0
        return o
