"""The abstract world's clock holds (src/patrolling_sim/tools/clock_hold.py, pure logic with
wall times passed in) and the run record's ``clock`` (runner.outcome.clock_record)."""
import os
import sys
from types import SimpleNamespace

import pytest

from patrolling_sim.common.protocol import MSG_DTA_IDLENESS, MSG_SSI_BID, MSG_SSI_TASK_REQUEST
from patrolling_sim.runner.outcome import clock_record

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "tools"))
from clock_hold import (GoHold, HoldCounter, MessageHold, StartHold, TimerReports,  # noqa
                        awaited_answer, reaction_deadline, totals)


def hold(team=4):
    return MessageHold(quiet=0.005, answer_quiet=0.02, limit=0.1, team_size=team)


def test_no_traffic_no_hold():
    h = hold()
    assert h.wait_until(1.0) is None and h.counter.holds == 0


def test_a_message_holds_until_quiet():
    h = hold()
    h.note(1.000, [2, MSG_DTA_IDLENESS, 5, 5, 1])
    assert h.wait_until(1.001) == pytest.approx(1.005)
    h.note(1.003, [1, MSG_DTA_IDLENESS, 5, 5, 2])        # more traffic: the quiet restarts
    assert h.wait_until(1.004) == pytest.approx(1.008)
    assert h.wait_until(1.008) is None
    assert h.counter.as_dict() == {"holds": 1, "timeouts": 0, "wall": 0.007}
    assert h.wait_until(1.009) is None and h.counter.holds == 1


def test_a_goal_is_traffic():
    h = hold()
    h.note(2.0)
    assert h.wait_until(2.001) == pytest.approx(2.005)


def test_a_task_request_waits_for_every_teammates_bid():
    h = hold(team=3)
    h.note(1.000, [0, MSG_SSI_TASK_REQUEST, 7, 300])
    assert h.wait_until(1.010) == pytest.approx(1.020)   # the longer quiet: answers due
    h.note(1.011, [1, MSG_SSI_BID, 7, 200])
    assert h.wait_until(1.012) == pytest.approx(1.031)
    h.note(1.013, [2, MSG_SSI_BID, 7, 100])              # every teammate answered
    assert h.wait_until(1.014) == pytest.approx(1.018)   # the short quiet again
    assert h.wait_until(1.018) is None


def test_silence_ends_the_wait_for_bids():
    h = hold()
    h.note(1.000, [0, MSG_SSI_TASK_REQUEST, 7, 300])
    h.note(1.002, [3, MSG_SSI_BID, 7, 100])              # robots 1 and 2 stay silent
    assert h.wait_until(1.003) == pytest.approx(1.022)
    assert h.wait_until(1.022) is None
    h.note(2.000, [2, MSG_DTA_IDLENESS, 1])              # the request is forgotten
    assert h.wait_until(2.001) == pytest.approx(2.005)


def test_a_hold_is_bounded_and_counted_as_timed_out():
    h = hold()
    t = 1.0
    h.note(t, [0, MSG_DTA_IDLENESS, 1])
    assert h.wait_until(t) is not None
    while t < 1.1:                                       # a chatty agent: never quiet
        t += 0.004
        h.note(t, [0, MSG_DTA_IDLENESS, 1])
        until = h.wait_until(t)
        if until is None:
            break
        assert until <= 1.1 + 1e-9
    assert until is None and t == pytest.approx(1.1, abs=0.005)
    assert h.counter.holds == 1 and h.counter.timeouts == 1
    assert h.wait_until(t + 0.001) is None               # the traffic so far is done with
    h.note(t + 0.002, [1, MSG_DTA_IDLENESS, 1])          # new traffic: a new hold
    assert h.wait_until(t + 0.003) is not None and h.counter.holds == 2


def test_limit_zero_never_holds():
    h = MessageHold(0.005, 0.02, 0.0, 4)
    h.note(1.0, [0, MSG_SSI_TASK_REQUEST, 7, 300])
    assert not h.enabled and h.wait_until(1.0) is None and h.counter.holds == 0
    with pytest.raises(ValueError):
        MessageHold(-1.0, 0.02, 0.1, 4)


def test_awaited_answer():
    assert awaited_answer([2, MSG_SSI_TASK_REQUEST, 7, 300]) == (MSG_SSI_BID, 7)
    assert awaited_answer([2, MSG_SSI_BID, 7, 300]) is None
    assert awaited_answer([-1, MSG_SSI_TASK_REQUEST, 7, 300]) is None   # not an agent's


def robot(done_at=None):
    return SimpleNamespace(done_at=done_at, hold_since=None, released=False)


def test_reaction_deadline_waits_then_releases():
    c = HoldCounter()
    robots = [robot(), robot(done_at=5.0), robot(done_at=5.5)]
    # sim 5.0 + reaction 0.08 reached by robot 1 only
    assert reaction_deadline(robots, 5.08, 0.05, c, now=10.0) == pytest.approx(10.05)
    assert c.holds == 1 and robots[1].hold_since == 10.0
    assert reaction_deadline(robots, 5.08, 0.05, c, now=10.02) == pytest.approx(10.05)
    assert c.holds == 1
    assert reaction_deadline(robots, 5.08, 0.05, c, now=10.05) is None
    assert robots[1].released and c.timeouts == 1
    assert reaction_deadline(robots, 5.08, 0.05, c, now=10.06) is None


def test_totals_sum_the_reasons():
    r, m = HoldCounter(3, 1, 0.25), HoldCounter(10, 0, 0.5)
    t = totals({"reaction": r, "message": m})
    assert (t["clock_holds"], t["hold_timeouts"], t["held_wall"]) == (13, 1, 0.75)
    assert t["hold_reasons"]["message"] == {"holds": 10, "timeouts": 0, "wall": 0.5}


def test_clock_record_from_either_simulator():
    abstract = {"sim_time": 300.0, "rtf": 19.5, "clock_holds": 13, "hold_timeouts": 1,
                "held_wall": 0.75, "hold_reasons": {"message": {"holds": 10}}}
    rec = clock_record(abstract, 20.0, 19.456)
    assert rec == {"pace_requested": 20.0, "pace_achieved": 19.46, "holds": 13,
                   "hold_timeouts": 1, "held_wall": 0.75,
                   "reasons": {"message": {"holds": 10}}}
    stage = {"sim_time": 300.0, "rtf": 3.9, "sync_waits": 42, "sync_timeouts": 2}
    rec = clock_record(stage, 4.0, 3.9)
    assert (rec["holds"], rec["hold_timeouts"], rec["held_wall"]) == (42, 2, None)
    assert "reasons" not in rec
    assert clock_record({}, 1.0, None) == {"pace_requested": 1.0, "pace_achieved": None,
                                           "holds": None, "hold_timeouts": None,
                                           "held_wall": None}


def test_auction_trace_measures_the_next_rounds_lag():
    from clock_hold import AuctionTrace
    t = AuctionTrace()
    t.note([0, MSG_SSI_TASK_REQUEST, 3, 100], 10.0, 1.0)
    t.note([0, MSG_SSI_TASK_REQUEST, 4, 100], 11.04, 1.1)    # 1.0 s auction, 0.04 s late
    t.note([0, MSG_SSI_TASK_REQUEST, 5, 100], 12.24, 1.2)    # 1.2 s auction, on time
    t.note([0, MSG_SSI_TASK_REQUEST, 6, 100], 30.0, 2.0)     # a later auction: not a round
    t.note([0, MSG_SSI_BID, 6, 50], 30.0, 2.001)
    assert t.lags == [pytest.approx(0.04), pytest.approx(0.0)]
    assert "n 2 median 0.040 max 0.040" in t.summary()


def test_auction_timers_mark_where_an_auction_may_end():
    from clock_hold import AuctionTimers
    t = AuctionTimers()
    t.note([1, MSG_SSI_TASK_REQUEST, 7, 300], 10.0)
    t.note([-1, MSG_SSI_TASK_REQUEST, 7, 300], 10.0)     # not an agent's: ignored
    t.note([2, MSG_SSI_BID, 7, 100], 10.0)               # not a request: ignored
    assert not t.reached(10.98)
    assert t.reached(11.0)                               # 1.0 s: an auction of no task
    assert not t.reached(11.0) and not t.reached(11.08)  # each end once
    assert t.reached(11.1)
    t.note([1, MSG_SSI_TASK_REQUEST, 8, 300], 11.1)      # the next round replaces them
    assert not t.reached(12.0) and t.reached(12.1)
    assert t.reached(14.1) and not t.ends                # 3 s at most: nothing left


def test_go_hold_from_last_ready_until_go_then_go_wait():
    h = GoHold(team=2, go_wait=0.5, announce_wait=2.0)
    assert h.until(0.0) is None
    assert not h.note(1.0, [0, 10, 1]) and h.until(1.0) is None      # one robot ready
    h.note(1.1, [0, 10, 1])                                            # announced again
    assert h.until(1.1) is None
    h.note(1.2, [1, 10, 1])                                            # the team is ready
    assert h.until(1.2) == 3.2
    assert h.note(1.25, [-1, 10, 100])                                 # GO
    assert h.until(1.3) == 1.75
    assert h.until(1.75) is None and h.counter.timeouts == 0
    assert not h.note(2.0, [-1, 10, 100])                              # GO again: nothing new
    assert h.until(2.0) is None


def test_go_hold_times_out_without_go_and_waits_no_more():
    h = GoHold(team=1, go_wait=0.5, announce_wait=2.0)
    h.note(0.0, [0, 10, 1])
    assert h.until(1.0) == 2.0
    assert h.until(2.0) is None and h.counter.timeouts == 1
    h.note(3.0, [0, 10, 1])                                            # a late re-announcement
    assert h.until(3.0) is None
    assert h.note(4.0, [-1, 10, 100]) and h.until(4.1) == 4.5          # GO still holds
    assert h.until(4.5) is None and h.counter.timeouts == 1


def test_go_hold_off_and_bad_wait():
    h = GoHold(team=1, go_wait=0.0)
    h.note(0.0, [0, 10, 1])
    assert h.note(0.1, [-1, 10, 100]) and h.until(0.1) is None
    with pytest.raises(ValueError, match="go_wait"):
        GoHold(team=1, go_wait=-1.0)


def test_start_hold_from_the_first_step_until_the_team_is_ready():
    h = StartHold(team=2, wait=10.0)
    h.note([0, 10, 1])                                  # before the first step: noted
    assert not h.holding(0.5)                           # not begun: the clock may step
    h.begin(1.0)
    assert h.holding(1.5) and h.counter.holds == 1
    h.note([5, 10, 1])                                  # not of the team
    h.note([0, 12])                                     # not an announcement
    assert h.holding(2.0)
    h.note([1, 10, 1])                                  # the team is ready
    assert not h.holding(2.1) and h.counter.timeouts == 0
    h.begin(3.0)                                        # ended holds do not begin again
    assert not h.holding(3.1) and h.counter.holds == 1


def test_start_hold_ends_at_go_or_times_out():
    h = StartHold(team=3, wait=10.0)
    h.begin(0.0)
    h.note([-1, 10, 100])                               # GO (the world missed an announcement)
    assert not h.holding(0.1) and h.counter.timeouts == 0
    h = StartHold(team=1, wait=10.0)
    h.begin(0.0)
    assert h.holding(9.9)
    assert not h.holding(10.0) and h.counter.timeouts == 1
    h.note([0, 10, 1])
    assert not h.holding(10.1) and h.counter.timeouts == 1


def test_start_hold_off_and_bad_wait():
    h = StartHold(team=1, wait=0.0)
    h.begin(0.0)
    assert not h.holding(0.0) and h.counter.holds == 0
    with pytest.raises(ValueError, match="start_wait"):
        StartHold(team=1, wait=-1.0)


def test_timer_reports_hold_where_a_timer_is_due_until_it_fired():
    r = TimerReports()
    assert r.waiting(5.0) == []                         # no reports: nothing to wait for
    r.note("/agents", -1.0, 1.4370)                     # a timer due at 1.437
    r.note("/robot_1", -1.0, 1.40)
    assert r.waiting(1.42) == ["/robot_1"]              # the first step at or after 1.40
    assert r.waiting(1.44) == ["/robot_1", "/agents"]   # both due, earliest first
    r.note("/robot_1", 1.44, 2.44)                      # fired at 1.44; next at 2.44
    assert r.waiting(1.44) == ["/agents"]
    r.note("/agents", 1.44, -1.0)                       # fired; nothing pending
    assert r.waiting(1.44) == [] and r.waiting(100.0) == ["/robot_1"]
    assert r.waiting(2.44 - 1e-7) == ["/robot_1"]       # within the scheduler's tolerance


def test_timer_reports_give_up_until_the_next_report():
    r = TimerReports()
    r.note("/gone", 0.0, 3.0)
    assert r.waiting(3.0) == ["/gone"]
    r.give_up(["/gone"])                                # its wait timed out
    assert r.waiting(3.0) == [] and r.waiting(9.0) == []
    r.note("/gone", 3.5, 4.0)                           # it reports again: waited for again
    assert r.waiting(4.0) == ["/gone"]


def test_reports_of_handled_events():
    r = TimerReports()
    assert not r.reports(2) and r.has_handled(2, 10.0)     # no reports: nothing to wait for
    r.note("/agents", -1.0, 5.0, robot=2, at=1.50)          # robot 2 handled GO at 1.50
    assert r.reports(2) and not r.reports(0)
    assert r.has_handled(2, 1.50) and not r.has_handled(2, 7.38)
    r.note("/agents", -1.0, 5.0, robot=2, at=7.38)          # its arrival at 7.38
    assert r.has_handled(2, 7.38) and not r.has_handled(2, 7.40)
    r.note("/agents", 5.0, 8.0, robot=2, at=7.20)           # an older reading is no news
    assert r.has_handled(2, 7.38)
    assert r.waiting(8.0) == ["/agents"]                    # the timer part of the report
