"""The agents' timer scheduler (patrolling_sim.ros.sim_timers) under simulated time, in
this process without a master: the order timers fire in and the reports the world reads
(``[done, next]``, ``[done, next, robot, t]``)."""
import threading
import time

import pytest

rospy = pytest.importorskip("rospy")
from patrolling_sim.ros import sim_timers  # noqa: E402


class FakePub:
    def __init__(self):
        self.sent = []

    def publish(self, msg):
        self.sent.append(list(msg.data))


def wait_for(cond, timeout=10.0):
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.005)


@pytest.fixture
def sim_clock():
    """Simulated ROS time in this process (restored to wall time afterwards)."""
    rt = rospy.rostime
    saved = (rt._rostime_initialized, rt._rostime_current)
    rt.set_rostime_initialized(True)

    def set_time(sec):
        rt._set_rostime(rospy.Time.from_sec(sec))
    set_time(1.0)
    yield set_time
    rt._rostime_initialized, rt._rostime_current = saved


def test_timers_fire_in_deadline_order_and_are_reported(sim_clock):
    s = sim_timers.TimerScheduler(report=False)
    s._pub = pub = FakePub()
    fired = []
    lock = threading.Lock()

    def note(name):
        with lock:
            fired.append((name, rospy.get_time()))
    try:
        s.call_at(2.5, lambda: note("b"))
        assert pub.sent == [[-1.0, 2.5]]                # a new earliest deadline: reported
        s.call_at(2.5, lambda: note("c"))
        s.call_at(3.0, lambda: note("d"))
        assert len(pub.sent) == 1                       # not earlier: no report
        s.call_at(2.0, lambda: note("a"))
        assert pub.sent[-1] == [-1.0, 2.0]
        sim_clock(1.98)
        time.sleep(0.05)
        assert fired == []
        sim_clock(2.52)                                 # a step past 2.0 and 2.5
        wait_for(lambda: len(fired) == 3 and pub.sent[-1][0] == 2.52)
        assert [n for n, _ in fired] == ["a", "b", "c"]  # deadline, then creation order
        assert pub.sent[-1] == [2.52, 3.0]              # fired through 2.52; next at 3.0
        d = s.call_at(3.5, lambda: note("e"))
        d.shutdown()                                    # cancelled before its deadline
        sim_clock(3.0)
        wait_for(lambda: pub.sent[-1][0] == 3.0)
        assert pub.sent[-1] == [3.0, -1.0]              # 3.5 cancelled: nothing pending
        sim_clock(4.0)
        time.sleep(0.05)
        assert [n for n, _ in fired] == ["a", "b", "c", "d"]
        s.handled(7)
        assert pub.sent[-1] == [3.0, -1.0, 7.0, 4.0]    # robot 7 handled an event at 4.0
    finally:
        s.close()


def test_a_cancelled_earliest_timer_is_reported_done(sim_clock):
    s = sim_timers.TimerScheduler(report=False)
    s._pub = pub = FakePub()
    try:
        t = s.call_at(2.0, lambda: None)
        s.call_at(5.0, lambda: None)
        t.shutdown()
        sim_clock(2.0)          # nothing fires at 2.0, but the world waits there: report
        wait_for(lambda: pub.sent[-1][0] == 2.0)
        assert pub.sent[-1] == [2.0, 5.0]
    finally:
        s.close()


def test_no_report_under_wall_clock():
    s = sim_timers.TimerScheduler(report=False)
    s._pub = pub = FakePub()
    rt = rospy.rostime
    saved = (rt._rostime_initialized, rt._rostime_current)
    rt.set_rostime_initialized(True)
    rt._rostime_current = None              # wall-clock time
    try:
        s.call_at(time.time() + 60.0, lambda: None)
        assert pub.sent == []
    finally:
        s.close()
        rt._rostime_initialized, rt._rostime_current = saved


def test_delivery_waits_until_every_local_agent_read_every_local_message():
    d = sim_timers.Delivery()
    d.add_agent(0)
    d.add_agent(1)
    assert d.wait(0.01)                     # nothing sent: nothing to wait for
    d.sent()                                # robot 0 publishes
    d.sent()                                # robot 1 publishes
    d.received(0, -1)                       # the monitor's message: not counted
    d.received(0, 0)
    d.received(0, 1)
    d.received(1, 0)
    assert not d.wait(0.01)                 # robot 1 has not read robot 1's message yet
    threading.Timer(0.05, d.received, (1, 1)).start()
    assert d.wait(5.0)                      # ... and then it has
    d.received(1, 7)                        # a robot of another process: not counted
    assert d.wait(0.01)
