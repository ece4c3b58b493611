"""move_base's goal execution (the action's execute callback, the control loop and the
recovery behaviours), mixed into :class:`spqrel_nav_lite.move_base_node.MoveBase`, which
provides the inputs (pose, laser, obstacle memory), the planner and the outputs.

The control loop is written once, as a generator (:meth:`GoalExecution.goal_task`) that
yields where it waits (:mod:`~spqrel_nav_lite.goal_waits`): for the next control cycle
(:class:`~spqrel_nav_lite.goal_waits.NextCycle`: the first odometry a period newer than the
one the last command used), for a moment of ROS time
(:class:`~spqrel_nav_lite.goal_waits.SleepUntil`, the recoveries' and the pose wait's rate) or
for a plan (:class:`~spqrel_nav_lite.goal_waits.PlanDone`). Two drivers run it:

- :meth:`GoalExecution.execute`, actionlib's execute callback, blocks its thread at every
  wait and makes its plans itself (a thread per robot: the standalone ``move_base`` and
  ``robot_nav``);
- :class:`~spqrel_nav_lite.control_loop.ControlLoop` runs the goals of many robots of a
  ``nav_host`` in one thread (``~control_threads`` of them, default 1), resuming each robot's
  generator when its wait is over; plans that may search run in a planning thread beside it
  (docs/navigation.md, "Threads").

Both run the same code on the same inputs; only who waits, and which thread makes the plans
that may search, differ.
"""
import math

import numpy as np
import rospy
from move_base_msgs.msg import MoveBaseFeedback, MoveBaseResult

from spqrel_nav_lite.controller import compute_command
from spqrel_nav_lite.geometry import compose
from spqrel_nav_lite.goal_waits import NextCycle, PlanDone, Rate, throw_into
from spqrel_nav_lite.planner import PlanningError, path_blocked, path_length
from spqrel_nav_lite.ros_util import fill_pose, strip_slash


class Aborted(Exception):
    pass


class GoalProgress:
    """The progress of one goal, by which :meth:`GoalExecution.run_goal` decides when the
    robot is stuck: the least remaining cost seen and when (``best_remaining``,
    ``best_time``), since when the robot has been blocked (``blocked_since``, None if it is
    not) and by what (``blocked_by``, for the log), the recoveries made and the time of the
    last plan (``last_plan``). Starts with the current ROS time as the last plan's and the
    best's."""

    def __init__(self):
        self.last_plan = rospy.get_time()
        self.best_remaining, self.best_time = math.inf, rospy.get_time()
        self.blocked_since = None
        self.blocked_by = "no path around it"    # the last cause of blocked_since
        self.recoveries = 0

    def no_path(self, now):
        """A re-plan found no path at ROS time ``now``: blocked since then (if not already)."""
        if self.blocked_since is None:
            self.blocked_since = now
        self.blocked_by = "no path around it"

    def observe(self, remaining, blocked, v, now):
        """One control cycle at ROS time ``now``: ``remaining`` cost to the goal, whether the
        command was ``blocked``, ``v`` the speed of the previous command (above 0.05 m/s and
        not blocked, the robot is no longer blocked). Progress counts from 0.1 m on."""
        if remaining < self.best_remaining - 0.1:
            self.best_remaining, self.best_time = remaining, now
        if blocked:
            self.blocked_since = self.blocked_since if self.blocked_since is not None else now
            self.blocked_by = "stopped in front of it"
        elif v > 0.05:
            self.blocked_since = None

    def stuck(self, now, blocked_patience, controller_patience):
        """Whether the robot has been blocked for more than ``blocked_patience`` s or made no
        progress for more than ``controller_patience`` s."""
        return (self.blocked_since is not None and now - self.blocked_since > blocked_patience) \
            or now - self.best_time > controller_patience

    def restart(self):
        """After a recovery: not blocked, no progress seen, last plan now (ROS time)."""
        self.blocked_since = None
        self.best_remaining, self.best_time = math.inf, rospy.get_time()
        self.last_plan = rospy.get_time()


class GoalExecution:
    def execute(self, goal_msg):
        """actionlib's execute callback: run the goal in this thread, blocking at its waits."""
        task = self.goal_task(goal_msg)
        wait = next(task, None)
        while wait is not None:
            try:
                wait.block(self)
            except rospy.ROSInterruptException as e:
                wait = throw_into(task, e)
                continue
            wait = next(task, None)

    def goal_task(self, goal_msg):
        """The goal (and the goals that preempt it) from start to its terminal state, as a
        generator of waits (module notes)."""
        while True:
            try:
                nxt = yield from self.run_goal(goal_msg)
            except Aborted as e:
                self.stop()
                rospy.logwarn("%smove_base: goal aborted: %s", self.robot_ns, e)
                self.server.set_aborted(MoveBaseResult(), str(e))
                return
            except rospy.ROSInterruptException:
                self.end_at_shutdown()
                return
            except Exception as e:     # never leave the robot driving on a bug
                self.stop()
                rospy.logerr("%smove_base: internal error: %r", self.robot_ns, e)
                self.server.set_aborted(MoveBaseResult(), f"internal error: {e!r}")
                return
            self.stop()
            if nxt is None:
                self.end_at_shutdown()
                return
            goal_msg = nxt

    def planned(self, pose, goal, elsewhere=True, **kwargs):
        """:meth:`make_plan`'s path (or its PlanningError): computed here, or, if
        ``elsewhere``, by the planning thread of this robot's :class:`ControlLoop` while the
        loop goes on with the other robots' cycles (a plan that searches takes tens of
        milliseconds on a large map). The execute thread of a robot computes it itself."""
        loop = self.control_loop
        if loop is None or not elsewhere:
            return self.make_plan(pose, goal, **kwargs)
        future = loop.plan(self.make_plan, pose, goal, **kwargs)
        yield PlanDone(future)
        return future.result()

    def end_at_shutdown(self):
        """Every goal ends in a terminal state: the control loop also ends when the node shuts
        down (rospy.is_shutdown(), or a sleep raising ROSInterruptException) with the goal
        still active; it is then aborted, before actionlib would do it with a warning."""
        if not self.server.is_active():
            return
        try:
            self.server.set_aborted(MoveBaseResult(), "navigation shutting down")
        except Exception as e:  # the result publisher may already be closed: nothing to tell
            rospy.logdebug("%smove_base: aborting the goal at shutdown: %r", self.robot_ns, e)

    def run_goal(self, goal_msg):
        """Drive to the goal. Returns a new goal if preempted by one, None when finished.

        Raises:
            Aborted: the goal failed; the message is the reason.
        """
        goal = self._goal_position(goal_msg)
        rate = Rate(self.frequency)
        dt = 1.0 / self.frequency
        start = rospy.get_time()
        pose = self.pose()
        while pose is None:
            if rospy.get_time() - start > self.localization_timeout:
                raise Aborted(f"no pose: nothing on amcl_pose/odom for "
                              f"{self.localization_timeout:.0f} s")
            if self.server.is_preempt_requested():
                return self.preempted()
            yield rate.sleep()
            pose = self.pose()
        # the stock move_base begins every control cycle, the goal's first included, by
        # publishing the robot's pose as feedback, before it plans: an agent hears from a new
        # goal at once (the original's agents clear their interference flag on a feedback;
        # they re-check it 1/30 s after a resend and, without one, stopped again every 3 s)
        feedback = MoveBaseFeedback()
        feedback.base_position.header.frame_id = self.global_frame
        last_feedback = rospy.get_time()
        self._publish_feedback(feedback, pose, rospy.Time.from_sec(last_feedback))
        self.laser(pose)
        path = yield from self._first_plan(pose, goal)
        timeout = self.goal_timeout if self.goal_timeout > 0 else \
            30.0 + 4.0 * path_length(path) / self.cp.max_vel_x
        deadline = start + timeout
        index = 0
        progress = GoalProgress()
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
            path, index = yield from self._replanned(pose, goal, path, index, progress, now)
            cmd = compute_command(pose, self.v, self.w, path, index, near, dt, self.cp, dynamic)
            index = cmd.index
            if cmd.done:
                self.stop()
                self.server.set_succeeded(MoveBaseResult(), "goal reached")
                return None
            remaining = self.planner.path_cost(pose[:2])
            if not math.isfinite(remaining):
                remaining = path_length(path[index:])
            progress.observe(remaining, cmd.blocked, self.v, now)
            if progress.stuck(now, self.blocked_patience, self.controller_patience):
                res, path = yield from self._recover_when_stuck(progress, goal, path, rate)
                if res is not None:
                    return res
                index = 0
                continue
            self.send(cmd.v, cmd.w)
            if now - last_feedback >= self.feedback_period - 1e-6:
                last_feedback = now
                self._publish_feedback(feedback, pose, rospy.Time.now())
            yield NextCycle(dt, used_stamp)
        return None

    def _publish_feedback(self, feedback, pose, stamp):
        """Publish ``pose`` as the goal's feedback (``feedback``: the goal's message, reused)."""
        feedback.base_position.header.stamp = stamp
        fill_pose(feedback.base_position.pose, pose)
        self.server.publish_feedback(feedback)

    def _goal_position(self, goal_msg):
        """(x, y) of the goal of ``goal_msg`` (a MoveBaseGoal). Raises Aborted if its frame
        is neither empty nor the global frame, or if the position is not finite."""
        frame = strip_slash(goal_msg.target_pose.header.frame_id)
        if frame not in ("", self.global_frame):
            raise Aborted(f"goal frame '{frame}' is not the global frame "
                          f"'{self.global_frame}'")
        gp = goal_msg.target_pose.pose.position
        goal = (gp.x, gp.y)
        if not (math.isfinite(gp.x) and math.isfinite(gp.y)):
            raise Aborted("goal position is not finite")
        return goal

    def _first_plan(self, pose, goal):
        """The goal's first path (generator of waits, as :meth:`planned`). If there is none,
        the temporary obstacles are dropped (planner and obstacle memory) and the static map
        alone is tried, unless the goal itself is bad. Raises Aborted with the goal's fault,
        or with the first planning error if the static map has no path either."""
        try:
            path = yield from self.planned(pose, goal)
        except PlanningError as e:
            self.planner.clear_obstacles()
            try:    # a bad goal is final
                self.planner.check_goal(goal[0], goal[1], self.cp.xy_goal_tolerance)
            except PlanningError as bad:
                raise Aborted(str(bad)) from None
            try:    # maybe only temporary obstacles are in the way: try the static map
                with self.lock:
                    self.memory.clear()
                path = yield from self.planned(pose, goal, with_obstacles=False)
            except PlanningError:
                raise Aborted(str(e)) from None
        return path

    def _replanned(self, pose, goal, path, index, progress, now):
        """(path, index) after the re-planning due at ROS time ``now`` (generator of waits):
        periodic (every 1 / ``planner_frequency`` s, from the navigation function at hand, in
        this thread), and at once (at most every 0.5 s) when a remembered obstacle lies on the
        path within 3 m of ``index`` (with the current obstacles, possibly in the planning
        thread). A new path starts at index 0; a failed re-plan keeps ``path`` and ``index``
        and marks ``progress`` blocked (:meth:`GoalProgress.no_path`)."""
        replan = self.planner_frequency > 0 and \
            now - progress.last_plan >= 1.0 / self.planner_frequency
        with self.lock:
            obst = self.memory.points()
        refresh = False
        if len(obst) and now - progress.last_plan >= 0.5 and \
                path_blocked(path, obst, self.cp.robot_radius + self.cp.safety_margin, index,
                             3.0) is not None:
            replan = refresh = True
        if replan:
            progress.last_plan = now
            try:
                path = yield from self.planned(pose, goal, refresh=refresh, elsewhere=refresh)
                index = 0
            except PlanningError as e:
                progress.no_path(now)
                rospy.logdebug("%smove_base: replanning failed: %s", self.robot_ns, e)
        return path, index

    def _recover_when_stuck(self, progress, goal, path, rate):
        """One more recovery (:meth:`recover`), then a new plan (generator of waits): returns
        (the new goal if preempted by one, else None; the new path, or ``path`` if none).
        ``progress`` restarts (:meth:`GoalProgress.restart`) unless preempted by a new goal.
        Raises Aborted once more than ``max_recoveries`` recoveries were needed."""
        progress.recoveries += 1
        reason = f"blocked by an obstacle ({progress.blocked_by})" \
            if progress.blocked_since is not None \
            else f"no progress for {self.controller_patience:.0f} s"
        if progress.recoveries > self.max_recoveries:
            raise Aborted(f"{reason}; giving up after {self.max_recoveries} recoveries")
        rospy.loginfo("%smove_base: %s, recovery %d/%d", self.robot_ns, reason,
                      progress.recoveries, self.max_recoveries)
        res = yield from self.recover(progress.recoveries, goal, rate)
        if res is not None:
            return res, path
        pose = self.pose()
        try:
            path = yield from self.planned(pose, goal)
        except PlanningError:
            pass
        progress.restart()
        return None, path

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
            yield rate.sleep()
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
            yield rate.sleep()
        self.stop()
        # obstacles still seen stay in memory (so the new plan goes around them); the others
        # expire or are cleared by the beams that now pass through them
        return None
