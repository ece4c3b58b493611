"""The agents' timer order (patrolling_sim.common.timer_heap): deadlines fixed when made,
due timers in (deadline, creation) order, cancelled ones never returned."""
import pytest

from patrolling_sim.common.timer_heap import TOLERANCE, TimerHeap


def test_due_in_deadline_then_creation_order():
    h = TimerHeap()
    fired = []
    for name, t in (("a", 2.0), ("b", 1.0), ("c", 2.0), ("d", 1.5)):
        h.push(t, lambda n=name: fired.append(n))
    assert h.next_deadline() == 1.0
    for t in h.pop_due(2.0):
        t.fn()
    assert fired == ["b", "d", "a", "c"]
    assert len(h) == 0 and h.next_deadline() is None


def test_not_due_before_deadline_but_within_tolerance():
    h = TimerHeap()
    h.push(0.1 + 0.2, lambda: None)                 # 0.30000000000000004
    assert h.pop_due(0.29) == []
    assert len(h.pop_due(0.3)) == 1                 # a clock summed from steps: 0.3
    h.push(1.0, lambda: None)
    assert h.pop_due(1.0 - 10 * TOLERANCE) == []


def test_cancelled_timers_are_dropped():
    h = TimerHeap()
    a = h.push(1.0, lambda: None)
    b = h.push(2.0, lambda: None)
    a.shutdown()
    assert h.next_deadline() == 2.0
    assert h.pop_due(5.0) == [b]


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_deadline_must_be_finite(bad):
    with pytest.raises(ValueError, match="finite"):
        TimerHeap().push(bad, lambda: None)
