"""move_base's goal execution (the action's execute callback, the control loop and the
recovery behaviours), mixed into :class:`spqrel_nav_lite.move_base_node.MoveBase`, which
provides the inputs (pose, laser, obstacle memory), the planner and the outputs.

The control loop is written once, as a generator (:meth:`GoalExecution.goal_task`) that
yields where it waits: for the next control cycle (:class:`NextCycle`: the first odometry a
period newer than the one the last command used), for a moment of ROS time
(:class:`SleepUntil`, the recoveries' and the pose wait's rate) or for a plan
(:class:`PlanDone`). Two drivers run it:

- :meth:`GoalExecution.execute`, actionlib's execute callback, blocks its thread at every
  wait and makes its plans itself (a thread per robot: the standalone ``move_base`` and
  ``robot_nav``);
- :class:`ControlLoop` runs the goals of many robots of a ``nav_host`` in one thread
  (``~control_threads`` of them, default 1), resuming each robot's generator when its wait is
  over; plans that may search run in a planning thread beside it. A thread per robot cost a
  process hosting 16 robots tens of thousands of thread switches per second, and the CPU
  they take (docs/navigation.md, "Threads"; docs/benchmarks/runner.md, "Fewer threads").

Both run the same code on the same inputs; only who waits, and which thread makes the plans
that may search, differ.
"""
import concurrent.futures
import math
import threading

import numpy as np
import rospy
from move_base_msgs.msg import MoveBaseFeedback, MoveBaseResult

from spqrel_nav_lite.controller import compute_command
from spqrel_nav_lite.geometry import compose
from spqrel_nav_lite.planner import PlanningError, path_blocked, path_length
from spqrel_nav_lite.ros_util import fill_pose, strip_slash


class Aborted(Exception):
    pass


class NextCycle:
    """Wait for the next control cycle: odometry at least ~``period`` newer than
    ``used_stamp`` (the odometry the last command was computed from), or ``deadline`` (ROS
    time) if odometry stops (see :meth:`MoveBase.wait_cycle`)."""
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
    """Wait for a plan that a :class:`ControlLoop`'s planning thread computes."""
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


class GoalExecution:
    def execute(self, goal_msg):
        """actionlib's execute callback: run the goal in this thread, blocking at its waits."""
        task = self.goal_task(goal_msg)
        wait = next(task, None)
        while wait is not None:
            try:
                wait.block(self)
            except rospy.ROSInterruptException as e:
                wait = _throw(task, e)
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
        """Drive to the goal. Returns a new goal if preempted by one, None when finished."""
        frame = strip_slash(goal_msg.target_pose.header.frame_id)
        if frame not in ("", self.global_frame):
            raise Aborted(f"goal frame '{frame}' is not the global frame "
                          f"'{self.global_frame}'")
        gp = goal_msg.target_pose.pose.position
        goal = (gp.x, gp.y)
        if not (math.isfinite(gp.x) and math.isfinite(gp.y)):
            raise Aborted("goal position is not finite")
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
        self.laser(pose)
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
        timeout = self.goal_timeout if self.goal_timeout > 0 else \
            30.0 + 4.0 * path_length(path) / self.cp.max_vel_x
        deadline = start + timeout
        index = 0
        last_plan = rospy.get_time()
        best_remaining, best_time = math.inf, rospy.get_time()
        blocked_since = None
        blocked_by = "no path around it"    # the last cause of blocked_since, for the log
        recoveries = 0
        feedback = MoveBaseFeedback()
        feedback.base_position.header.frame_id = self.global_frame
        last_feedback = -math.inf
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
            # periodic replanning (the navigation function makes it cheap unless the
            # obstacle set changed), and immediate replanning if the path is blocked
            replan = self.planner_frequency > 0 and now - last_plan >= 1.0 / self.planner_frequency
            with self.lock:
                obst = self.memory.points()
            refresh = False
            if len(obst) and now - last_plan >= 0.5 and \
                    path_blocked(path, obst, self.cp.robot_radius + self.cp.safety_margin, index,
                                 3.0) is not None:
                replan = refresh = True
            if replan:
                last_plan = now
                try:
                    # from the navigation function at hand (no search) unless the obstacles
                    # changed: the cheap periodic re-plans stay in this thread
                    path = yield from self.planned(pose, goal, refresh=refresh,
                                                   elsewhere=refresh)
                    index = 0
                except PlanningError as e:
                    if blocked_since is None:
                        blocked_since = now
                    blocked_by = "no path around it"
                    rospy.logdebug("%smove_base: replanning failed: %s", self.robot_ns, e)
            cmd = compute_command(pose, self.v, self.w, path, index, near, dt, self.cp, dynamic)
            index = cmd.index
            if cmd.done:
                self.stop()
                self.server.set_succeeded(MoveBaseResult(), "goal reached")
                return None
            remaining = self.planner.path_cost(pose[:2])
            if not math.isfinite(remaining):
                remaining = path_length(path[index:])
            if remaining < best_remaining - 0.1:
                best_remaining, best_time = remaining, now
            if cmd.blocked:
                blocked_since = blocked_since if blocked_since is not None else now
                blocked_by = "stopped in front of it"
            elif self.v > 0.05:
                blocked_since = None
            stuck = (blocked_since is not None and now - blocked_since > self.blocked_patience) \
                or now - best_time > self.controller_patience
            if stuck:
                recoveries += 1
                reason = f"blocked by an obstacle ({blocked_by})" if blocked_since is not None \
                    else f"no progress for {self.controller_patience:.0f} s"
                if recoveries > self.max_recoveries:
                    raise Aborted(f"{reason}; giving up after {self.max_recoveries} recoveries")
                rospy.loginfo("%smove_base: %s, recovery %d/%d", self.robot_ns, reason,
                              recoveries, self.max_recoveries)
                res = yield from self.recover(recoveries, goal, rate)
                if res is not None:
                    return res
                pose = self.pose()
                try:
                    path = yield from self.planned(pose, goal)
                except PlanningError:
                    pass
                index = 0
                blocked_since = None
                best_remaining, best_time = math.inf, rospy.get_time()
                last_plan = rospy.get_time()
                continue
            self.send(cmd.v, cmd.w)
            if now - last_feedback >= self.feedback_period - 1e-6:
                last_feedback = now
                feedback.base_position.header.stamp = rospy.Time.now()
                fill_pose(feedback.base_position.pose, pose)
                self.server.publish_feedback(feedback)
            yield NextCycle(dt, used_stamp)
        return None

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


def _throw(task, exc):
    """Raise ``exc`` in the generator ``task`` at its current wait; its next wait, or None
    when it ended."""
    try:
        return task.throw(exc)
    except StopIteration:
        return None


class ControlLoop:
    """One thread that runs the goals of many robots (the :class:`GoalExecution` nodes of a
    ``nav_host``): each robot's goal is a generator of waits; the thread wakes when any
    hosted robot's odometry or goal arrives (:meth:`wake`) and resumes every robot whose
    wait is over, one after another. Plans that may search run in a second thread
    (:meth:`plan`, called by :meth:`GoalExecution.planned`), so that a robot's search does
    not hold up the other robots' commands; the robot itself waits for its plan, as its own
    thread would. A robot's new goal is accepted here when it has none
    running, as actionlib's execute thread would; a goal that preempts a running one is taken
    by the running generator itself (:meth:`GoalExecution.preempted`), as before.

    Falls back to a wake-up every ``idle`` wall seconds, so that waits in ROS time end even
    while no odometry arrives. ``is_shutdown``: when to stop (then every running goal gets
    ``ROSInterruptException`` at its wait, and ends as at a node's shutdown)."""

    def __init__(self, idle=0.05, is_shutdown=rospy.is_shutdown):
        self.idle = idle
        self.is_shutdown = is_shutdown
        self.nodes = []
        self._cond = threading.Condition()
        self._pending = False
        self._thread = threading.Thread(target=self._run, name="control_loop", daemon=True)
        self._planner = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="planner")
        self.wakeups = 0        #: passes over the hosted robots
        self.steps = 0          #: goal steps taken (waits that were over)

    def add(self, node):
        """Host ``node``'s goals (before :meth:`start`)."""
        node._task = node._wait = None
        self.nodes.append(node)

    def start(self):
        self._thread.start()

    def wake(self):
        with self._cond:
            self._pending = True
            self._cond.notify()

    def plan(self, fn, *args, **kwargs):
        """Run ``fn(*args, **kwargs)`` in the planning thread; a Future. The loop wakes when
        it is done."""
        future = self._planner.submit(fn, *args, **kwargs)
        future.add_done_callback(lambda _: self.wake())
        return future

    def join(self, timeout=None):
        self._thread.join(timeout)

    def _run(self):
        while not self.is_shutdown():
            with self._cond:
                if not self._pending:
                    self._cond.wait(self.idle)
                self._pending = False
            self.wakeups += 1
            for node in self.nodes:
                try:
                    self.steps += self._step(node)
                except Exception as e:     # never let one robot stop the others' loops
                    rospy.logerr("%smove_base: control loop: %r", node.robot_ns, e)
                    node._task = node._wait = None
                    self._abort(node, f"internal error: {e!r}")
        self._planner.shutdown(wait=False)
        interrupt = rospy.ROSInterruptException("ROS shutdown request")
        for node in self.nodes:
            if node._task is not None:
                _throw(node._task, interrupt)
                node._task = node._wait = None

    @staticmethod
    def _step(node):
        """Resume ``node``'s goal if its wait is over (or start its new goal): 1 if it
        stepped, else 0."""
        if node._task is None:
            if not node.server.is_new_goal_available():
                return 0
            node._task = node.goal_task(node.server.accept_new_goal())
            node._wait = None
        elif not node._wait.ready(node):
            return 0
        node._wait = next(node._task, None)
        if node._wait is None:
            node._task = None
            ControlLoop._abort(node, "goal ended without a result")   # as actionlib does
        return 1

    @staticmethod
    def _abort(node, text):
        """A goal that is still active when its generator is gone ends aborted (the robot
        stopped), so that no client waits for it forever."""
        if node.server.is_active():
            node.stop()
            node.server.set_aborted(MoveBaseResult(), text)
