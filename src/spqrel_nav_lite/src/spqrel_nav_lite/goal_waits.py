"""The waits that move_base's goal generator (:meth:`GoalExecution.goal_task
<spqrel_nav_lite.move_base_goal.GoalExecution.goal_task>`) yields, and how its drivers resume
it.

A wait has ``block(node)``, which blocks the calling thread until the wait is over (actionlib's
execute thread), and ``ready(node)``, which tells whether it is over without blocking (the
:class:`~spqrel_nav_lite.control_loop.ControlLoop` of many robots); ``node`` is the robot's
:class:`~spqrel_nav_lite.move_base_node.MoveBase`.
"""
import rospy


class NextCycle:
    """Wait for the next control cycle: odometry at least ~``period`` newer than
    ``used_stamp`` (the odometry the last command was computed from), or ``deadline`` (ROS
    time) if odometry stops (see
    :meth:`~spqrel_nav_lite.move_base_node.MoveBase.wait_cycle`)."""
    __slots__ = ("period", "used_stamp", "deadline")

    def __init__(self, period, used_stamp):
        self.period = period
        self.used_stamp = used_stamp
        self.deadline = rospy.get_time() + 1.5 * period

    def block(self, node):
        node.wait_cycle(self.period, self.used_stamp, self.deadline)

    def ready(self, node):
        return node.cycle_due(self.period, self.used_stamp) or rospy.get_time() >= self.deadline


class SleepUntil:
    """Wait until ROS time ``until`` (s)."""
    __slots__ = ("until",)

    def __init__(self, until):
        self.until = until

    def block(self, node):
        rospy.sleep(self.until - rospy.get_time())     # ROSInterruptException at shutdown

    def ready(self, node):
        return rospy.get_time() >= self.until


class PlanDone:
    """Wait for a plan that a :class:`~spqrel_nav_lite.control_loop.ControlLoop`'s planning
    thread computes."""
    __slots__ = ("future",)

    def __init__(self, future):
        self.future = future

    def block(self, node):
        self.future.result()

    def ready(self, node):
        return self.future.done()


class Rate:
    """rospy.Rate's schedule as waits: ``yield rate.sleep()`` waits until one period after
    the previous wake-up (and restarts from now if more than two periods behind, or if time
    went backwards), as ``rospy.Rate.sleep`` does."""

    def __init__(self, hz):
        self.period = 1.0 / hz
        self.last = rospy.get_time()

    def sleep(self):
        now = rospy.get_time()
        if now < self.last:
            self.last = now
        until = self.last + self.period
        self.last = until
        if now - self.last > 2 * self.period:
            self.last = now
        return SleepUntil(until)


def throw_into(task, exc):
    """Raise ``exc`` in the generator ``task`` at its current wait; its next wait, or None
    when it ended."""
    try:
        return task.throw(exc)
    except StopIteration:
        return None
