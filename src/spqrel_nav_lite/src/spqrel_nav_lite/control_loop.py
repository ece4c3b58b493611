"""The control loop of a ``nav_host``: one thread runs the goals of many robots.

A thread per robot (actionlib's execute thread) costs a process hosting many robots thread
switches and CPU of their own (docs/navigation.md, "Threads"); :class:`ControlLoop` instead
resumes each robot's goal generator (:meth:`GoalExecution.goal_task
<spqrel_nav_lite.move_base_goal.GoalExecution.goal_task>`, a generator of the waits of
:mod:`~spqrel_nav_lite.goal_waits`) when its wait is over.
"""
import concurrent.futures
import threading

import rospy
from move_base_msgs.msg import MoveBaseResult

from spqrel_nav_lite.goal_waits import throw_into


class ControlLoop:
    """One thread that runs the goals of many robots (the
    :class:`~spqrel_nav_lite.move_base_goal.GoalExecution` nodes of a ``nav_host``): each
    robot's goal is a generator of waits; the thread wakes when any hosted robot's odometry or
    goal arrives (:meth:`wake`) and resumes every robot whose wait is over, one after another.
    Plans that may search run in a second thread (:meth:`plan`, called by
    :meth:`~spqrel_nav_lite.move_base_goal.GoalExecution.planned`), so that a robot's search
    does not hold up the other robots' commands; the robot itself waits for its plan, as its
    own thread would. A robot's new goal is accepted here when it has none running, as
    actionlib's execute thread would; a goal that preempts a running one is taken by the
    running generator itself (:meth:`~spqrel_nav_lite.move_base_goal.GoalExecution.preempted`).

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
                throw_into(node._task, interrupt)
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
