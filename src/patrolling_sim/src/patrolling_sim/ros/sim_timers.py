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
"""
import threading

import rospy

from patrolling_sim.common.timer_heap import TimerHeap

#: wall s the thread waits at most between two looks at the clock and the heap
POLL = 0.5
#: s: the shortest delay; a zero delay fires at the next clock step, as with rospy.Timer
MIN_DELAY = 1e-3


class TimerScheduler:
    """Fires one-shot callbacks at absolute ROS times, from one daemon thread."""

    def __init__(self):
        self._heap = TimerHeap()
        self._cond = rospy.rostime.get_rostime_cond()
        self._thread = None

    def call_at(self, deadline, fn):
        """Run ``fn()`` (in the scheduler's thread; it takes its own locks) once ROS time
        reaches ``deadline`` (s). Returns a handle whose ``shutdown()`` cancels it."""
        with self._cond:
            t = self._heap.push(deadline, fn)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="sim_timers",
                                                daemon=True)
                self._thread.start()
            self._cond.notify_all()
        return t

    def _run(self):
        while not rospy.core.is_shutdown():
            with self._cond:
                now = rospy.get_time()
                due = self._heap.pop_due(now)
                if not due:
                    nxt = self._heap.next_deadline()
                    wait = POLL
                    if nxt is not None and rospy.rostime.is_wallclock():
                        wait = min(POLL, max(0.0, nxt - now))
                    self._cond.wait(wait)
                    continue
            for t in due:                 # outside the condition: callbacks take locks
                if t.cancelled or rospy.core.is_shutdown_requested():
                    continue
                try:
                    t.fn()
                except Exception as e:    # a failing callback must not stop the others
                    rospy.logerr("timer callback failed: %s", e)


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
