"""One-shot timers at absolute times, in a deterministic order: pure logic, no clock, no
threads (the ROS agents' scheduler, :mod:`patrolling_sim.ros.sim_timers`, drives it).

A timer is due once the clock reads its deadline (within :data:`TOLERANCE`). Timers due
together fire in the order of their deadlines, and timers with the same deadline in the
order they were created, so the same calls give the same order on any machine.
"""
import heapq
import itertools

#: s: a deadline counts as reached when the clock is at most this much short of it (the
#: clock's float seconds, summed from steps, miss an exact sum by ~1e-12)
TOLERANCE = 1e-6


class OneShot:
    """A scheduled callback. ``deadline`` (s), ``fn`` (called with no argument), and
    ``cancelled``; :meth:`shutdown` cancels it (a cancelled timer never fires)."""
    __slots__ = ("deadline", "seq", "fn", "cancelled")

    def __init__(self, deadline, seq, fn):
        self.deadline, self.seq, self.fn, self.cancelled = deadline, seq, fn, False

    def shutdown(self):
        """Cancel (the name of rospy.Timer's method, so callers treat both alike)."""
        self.cancelled = True

    def __lt__(self, other):
        return (self.deadline, self.seq) < (other.deadline, other.seq)


class TimerHeap:
    """Pending one-shot timers ordered by (deadline, creation)."""

    def __init__(self):
        self._heap = []
        self._seq = itertools.count()

    def __len__(self):
        """Timers pending, cancelled ones not yet dropped included."""
        return len(self._heap)

    def push(self, deadline, fn):
        """Schedule ``fn`` at time ``deadline`` (s, a finite float); returns its
        :class:`OneShot`. Raises ValueError for a deadline that is not finite."""
        deadline = float(deadline)
        if deadline != deadline or deadline in (float("inf"), float("-inf")):
            raise ValueError(f"timer deadline must be finite, got {deadline}")
        t = OneShot(deadline, next(self._seq), fn)
        heapq.heappush(self._heap, t)
        return t

    def next_deadline(self):
        """The earliest deadline of a timer not cancelled, or None."""
        while self._heap and self._heap[0].cancelled:
            heapq.heappop(self._heap)
        return self._heap[0].deadline if self._heap else None

    def pop_due(self, now):
        """Remove and return, in firing order, the timers not cancelled whose deadline the
        clock reading ``now`` (s) has reached."""
        due = []
        while self._heap and self._heap[0].deadline <= now + TOLERANCE:
            t = heapq.heappop(self._heap)
            if not t.cancelled:
                due.append(t)
        return due
