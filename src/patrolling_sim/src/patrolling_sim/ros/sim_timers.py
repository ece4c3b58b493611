"""The agents' one-shot timers on ROS time: one scheduler thread per process, absolute
deadlines (:class:`patrolling_sim.common.timer_heap.TimerHeap`).

Why not ``rospy.Timer``: a rospy timer is a thread of its own that reads the clock when the
thread first runs, not when the timer is made, and sleeps its period from there. On a busy
machine, or with several agents in one process (``patrol_agents``), the thread may first run
a few simulated steps later, and the timer then fires that much late, by a different amount
in every run. Here the deadline is the ROS time when :meth:`TimerScheduler.call_at` (or
:func:`call_later`) is called plus the delay, and timers due in the same step fire in the
order of their deadlines, then of their creation.

The thread waits on rospy's clock condition (notified by every ``/clock`` message) under
simulated time, and for the wall time left to the next deadline under wall-clock time.

Under simulated time the scheduler also tells the world where its timers are
(:data:`REPORT_TOPIC`, ``std_msgs/Float64MultiArray``, ``[done, next]``): ``done`` is the
clock reading through which every due timer has fired (its callbacks have returned), ``next``
the earliest pending deadline (-1 if none). It reports when a new timer becomes the earliest
and after it fired the timers due at a clock reading. :meth:`TimerScheduler.handled` adds
``[done, next, robot, t]``: robot ``robot``'s agent has handled an event (GO, a goal's
outcome) at clock reading ``t``, everything it sent for it already published. A world that
reads these reports keeps its clock at the first step at or after ``next`` until the report
that those timers fired (the abstract world, docs/abstract_world.md, "Agents' reports"; the
simulator ``patrol_stage2d``, its timer hold), and the abstract world also at a robot's
arrival until its agent has handled it, so that a timer's or an arrival's action goes out
at the same simulated step at any pace and load. Nothing in the topic API
the original's agents use changes; a world that does not read the reports loses nothing.
"""
import threading
import time

import rospy
from std_msgs.msg import Float64MultiArray

from patrolling_sim.common.timer_heap import TOLERANCE, TimerHeap

#: where the scheduler reports ``[done, next]`` (see the module's docstring)
REPORT_TOPIC = "/sim_timers"
#: ``next`` when no timer is pending
NO_DEADLINE = -1.0
#: the global parameter a world that reads the reports sets to true
READER_PARAM = "/sim_timers_reader"
#: wall s an agent waits at most for the reader's connection (see wait_for_reader)
READER_WAIT = 5.0
#: held while the timers due at one clock reading fire. The ROS glue takes it before it
#: hands a ``/results`` message to an agent, so a message reaches an agent before or after
#: such a batch, never between two of its timers: with several agents in one process whose
#: timers are due at the same step (robots that arrived together on grid), which agent's
#: timer saw the other's message would otherwise depend on thread scheduling.
batch_lock = threading.Lock()
#: wall s a report waits at most for the process's own messages to come back (Delivery)
DELIVERY_WAIT = 0.5


class Delivery:
    """The ``/results`` messages this process's agents sent, and how many of them each of
    its agents has received back (a message reaches every agent of the process, its sender
    included, through the process's own subscription). A report waits until every agent
    has received every message sent before it (:meth:`wait`), so that "handled" also means
    "its teammates in this process have read what it sent": the world's quiet window alone
    cannot tell when a loaded process has delivered a message to itself."""

    def __init__(self):
        self._cond = threading.Condition()
        self._sent = 0
        self._received = {}         # local agent id -> local messages received

    def add_agent(self, agent_id):
        """Agent ``agent_id`` lives in this process (before any message is sent)."""
        with self._cond:
            self._received[int(agent_id)] = self._sent

    def sent(self):
        """One message is about to be published by an agent of this process."""
        with self._cond:
            self._sent += 1

    def received(self, agent_id, sender):
        """Agent ``agent_id`` has handled a message of robot ``sender``."""
        with self._cond:
            if sender in self._received and agent_id in self._received:
                self._received[agent_id] += 1
                self._cond.notify_all()

    def wait(self, timeout=DELIVERY_WAIT):
        """Wait until every local agent has received every local message sent so far (at
        most ``timeout`` wall s: a lost message, a stopping node). True if they have."""
        with self._cond:
            target = self._sent
            return self._cond.wait_for(
                lambda: all(n >= target for n in self._received.values()), timeout)


#: the process's bookkeeping of its own messages
delivery = Delivery()

#: wall s the thread waits at most between two looks at the clock and the heap
POLL = 0.5
#: s: the shortest delay; a zero delay fires at the next clock step, as with rospy.Timer
MIN_DELAY = 1e-3


class TimerScheduler:
    """Fires one-shot callbacks at absolute ROS times, from one daemon thread."""

    def __init__(self, report=True):
        self._heap = TimerHeap()
        self._cond = rospy.rostime.get_rostime_cond()
        self._thread = None
        self._pub = (rospy.Publisher(REPORT_TOPIC, Float64MultiArray, queue_size=100)
                     if report else None)
        self._done = NO_DEADLINE        # clock reading through which due timers have fired
        self._reported = None           # the last ``next`` reported
        self._closed = False
        self._reader = False            # a world reads the reports (wait_for_reader)

    def wait_for_reader(self, timeout=READER_WAIT):
        """If a world reads the reports (:data:`READER_PARAM`), wait until it is connected
        (at most ``timeout`` wall s): a report sent before is lost, and a timer the world
        does not know of may fire steps late. Returns True if connected (or no reader)."""
        if self._pub is None or not rospy.get_param(READER_PARAM, False):
            return True
        self._reader = True
        end = time.monotonic() + timeout
        while self._pub.get_num_connections() == 0:
            if time.monotonic() >= end or rospy.core.is_shutdown_requested():
                rospy.logwarn("no connection to the world's %s reader after %g s; its clock "
                              "will not wait for this process's timers", REPORT_TOPIC,
                              timeout)
                return False
            time.sleep(0.01)
        return True

    def close(self):
        """End the scheduler's thread (pending timers never fire); the node's shutdown ends
        it too."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def call_at(self, deadline, fn):
        """Run ``fn()`` (in the scheduler's thread; it takes its own locks) once ROS time
        reaches ``deadline`` (s). Returns a handle whose ``shutdown()`` cancels it."""
        with self._cond:
            t = self._heap.push(deadline, fn)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="sim_timers",
                                                daemon=True)
                self._thread.start()
            if self._reported is None or t.deadline < self._reported:
                self._report()
            self._cond.notify_all()
        return t

    def handled(self, robot_id, wait=True):
        """Report that robot ``robot_id``'s agent has handled an event (GO, a goal's outcome)
        at the current clock reading: what it sent for it is already published. Call it
        after the handler, outside the agent's lock. With ``wait`` it first waits until the
        agents of this process have received what the agents sent (:class:`Delivery`; only
        if a world reads the reports); never wait in the thread that delivers ``/results``
        (it would wait for itself)."""
        if wait and self._reader:
            delivery.wait()
        with self._cond:
            self._report([float(robot_id), rospy.get_time()])

    def _report(self, extra=()):
        """Publish ``[done, next, *extra]`` (under ``self._cond``; under wall-clock time
        there is no world to tell, and nothing is sent)."""
        nxt = self._heap.next_deadline()
        self._reported = nxt
        if self._pub is None or rospy.rostime.is_wallclock():
            return
        try:
            self._pub.publish(Float64MultiArray(
                data=[self._done, NO_DEADLINE if nxt is None else nxt, *extra]))
        except rospy.ROSException:
            if not rospy.core.is_shutdown_requested():    # a closed topic while stopping
                raise

    def _run(self):
        while not rospy.core.is_shutdown():
            with self._cond:
                if self._closed:
                    return
                now = rospy.get_time()
                due = self._heap.pop_due(now)
                if not due:
                    if self._reported is not None and self._reported <= now + TOLERANCE:
                        self._done = max(self._done, now)     # it was cancelled meanwhile
                        self._report()
                    nxt = self._heap.next_deadline()
                    wait = POLL
                    if nxt is not None and rospy.rostime.is_wallclock():
                        wait = min(POLL, max(0.0, nxt - now))
                    self._cond.wait(wait)
                    continue
            with batch_lock:              # outside the condition: callbacks take locks
                for t in due:
                    if t.cancelled or rospy.core.is_shutdown_requested():
                        continue
                    try:
                        t.fn()
                    except Exception as e:    # a failing callback must not stop the others
                        rospy.logerr("timer callback failed: %s", e)
            if self._reader:
                delivery.wait()               # what the timers sent, read in this process
            with self._cond:
                self._done = max(self._done, now)
                self._report()


_scheduler = None
_scheduler_lock = threading.Lock()


def scheduler():
    """The process's scheduler (made on first use, inside an initialised rospy node)."""
    global _scheduler
    with _scheduler_lock:
        if _scheduler is None:
            _scheduler = TimerScheduler()
        return _scheduler


def call_later(delay, fn):
    """Run ``fn()`` ``delay`` s of ROS time from now (now: ``rospy.get_time()`` at this call;
    at least ``MIN_DELAY`` s, i.e. never in the calling step). Returns the handle."""
    return scheduler().call_at(rospy.get_time() + max(float(delay), MIN_DELAY), fn)
