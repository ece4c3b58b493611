"""The monitor node stamps a visit report when it takes the report under its lock
(patrolling_sim.ros.monitor_node, without a ROS master). rospy hands each publisher's
messages over on a thread of its own; a stamp taken before waiting for the lock let a report
that arrived later be recorded first, so times in the result files went back and idleness
samples came out negative (seen with 8 of the original's agents on a loaded machine: -0.4 s,
a file the report's own loader refuses)."""
import threading
import time

import pytest

rospy = pytest.importorskip("rospy", reason="rospy (Debian: python3-rospy) missing")
from std_msgs.msg import Int16MultiArray  # noqa: E402

from patrolling_sim.monitor.core import MonitorCore  # noqa: E402
from patrolling_sim.ros.monitor_node import MSG_TARGET_REACHED, Monitor  # noqa: E402


class WriterStub:
    def __init__(self):
        self.visits, self.samples = [], []

    def visit_row(self, t, rid, v):
        self.visits.append((t, rid, v))

    def idleness_row(self, now, rid, v, idleness, interferences):
        self.samples.append((now, rid, v, idleness))


def _monitor():
    m = Monitor.__new__(Monitor)                  # the glue only: no graph, no rospy node
    m.lock = threading.RLock()
    m.finished = False
    m.n_robots, m.alg = 2, "CR"
    m.core = MonitorCore(3, 2)
    m.core.start(0.0)
    m.writer = WriterStub()
    return m


def test_reports_waiting_for_the_lock_are_stamped_in_the_order_they_are_taken(monkeypatch):
    clock = [10.0]
    monkeypatch.setattr(rospy, "get_time", lambda: clock[0])
    m = _monitor()
    msg = Int16MultiArray(data=[1, MSG_TARGET_REACHED, 2])
    with m.lock:                                  # e.g. the loop writing a time row
        t = threading.Thread(target=m._on_results, args=(msg,))
        t.start()
        time.sleep(0.2)                           # the report's thread waits for the lock
        clock[0] = 12.0                           # ... while the clock goes on
        m._on_results(Int16MultiArray(data=[0, MSG_TARGET_REACHED, 2]))   # taken first
    t.join(10.0)
    # robot 0's report was taken first (at 12.0), robot 1's after it: times never go back
    assert [(rid, ts) for ts, rid, _ in m.writer.visits] == [(0, 12.0), (1, 12.0)]
    assert [s[3] for s in m.writer.samples] == [0.0]      # never a negative idleness
