"""The PatrolAgent life cycle (agent_core) driven by a fake world: order of events, resends,
interference, message delay and loss, END, redirect. Time is the fake's clock only."""
import heapq
import itertools

import pytest

from patrolling_sim.agent.core import (BACKUP_DURATION, INTERFERENCE_PAUSE, MAX_RESENDS,
                                       Effects, PatrolAgentCore)
from patrolling_sim.algorithms.base import PatrolStrategy

GO = [-1, 10, 100]
END = [-1, 10, 999]


class FakeWorld(Effects):
    """Records every effect in ``log`` (shared with the strategy) and runs timers."""

    def __init__(self, log):
        self.t = 0.0
        self.log_ = log
        self.timers = []
        self._n = itertools.count()
        self.goals = []           # (t, vertex, seq)
        self.ended = False

    def now(self):
        return self.t

    def publish(self, data):
        self.log_.append(("publish", self.t, list(data)))

    def send_goal(self, vertex, seq):
        self.goals.append((self.t, vertex, seq))
        self.log_.append(("goal", self.t, vertex))

    def cancel_goal(self):
        self.log_.append(("cancel", self.t))

    def call_later(self, delay, fn):
        heapq.heappush(self.timers, (self.t + delay, next(self._n), fn))

    def backup(self):
        self.log_.append(("backup", self.t))

    def clear_costmaps(self):
        self.log_.append(("clear", self.t))

    def end(self):
        self.ended = True

    def advance(self, dt):
        """Fire every timer due within ``dt`` s, in time order."""
        stop = self.t + dt
        while self.timers and self.timers[0][0] <= stop + 1e-12:
            t, _, fn = heapq.heappop(self.timers)
            self.t = max(self.t, t)
            fn()
        self.t = stop


class Scripted(PatrolStrategy):
    """Goes to the vertices of ``plan`` in turn; logs every hook it gets."""
    name = "_SCRIPTED"

    def __init__(self, driver, log, plan, graph_n=5):
        self.driver, self.log_, self.plan = driver, log, list(plan)
        self.id = 0
        self.decide_none = 0          # answer None this many times first
        self.fallback = 4

    def start(self, v, now):
        self.current = v
        self.log_.append(("start", now, v))

    def next_vertex(self, now):
        if self.decide_none:
            self.decide_none -= 1
            self.log_.append(("decide", now, None))
            return None
        v = self.plan.pop(0)
        self.log_.append(("decide", now, v))
        return v

    def on_arrival(self, v, now):
        self.current = v
        self.log_.append(("arrival", now, v))

    def send_results(self, now):
        self.log_.append(("share", now))
        self.driver.send([self.id, 40, 7])

    def on_message(self, data, now):
        self.log_.append(("message", now, list(data)))

    def on_goal_failed(self, v, now):
        self.log_.append(("failed", now, v))
        return self.fallback


def make(robot_id=0, plan=(1, 2, 3, 1, 2, 3), start=0, **kw):
    log = []
    world = FakeWorld(log)
    core = PatrolAgentCore(world, robot_id, start,
                           lambda d: Scripted(d, log, plan), seed=1, **kw)
    core.strategy.id = robot_id
    return core, world, log


def started(robot_id=0, **kw):
    """A core past GO and its start delay, heading to its first goal; log cleared."""
    core, world, log = make(robot_id, **kw)
    core.ready()
    core.on_results(GO)
    world.advance(1.0)
    assert core.phase == "patrol" and core.state == "moving"
    del log[:]
    return core, world, log


def kinds(log):
    return [e[0] if e[0] != "publish" else f"publish{e[2][1]}" for e in log]


def test_announce_until_go_then_start_sequence():
    core, world, log = make()
    core.ready()
    world.advance(4.5)
    assert [e[2] for e in log] == [[0, 10, 1]] * 3           # t = 0, 2, 4
    del log[:]
    core.on_results([0, 40, 1])                                # own: ignored
    core.on_results([1, 40, 5])                                # before GO: dropped
    core.on_results(GO)
    core.on_results([1, 40, 6])                                # during the start delay: kept
    world.advance(1.0)
    # announcements stopped; start delay U(0, 1) s; then the original's order
    assert kinds(log) == ["clear", "start", "message", "decide", "publish11", "share",
                          "publish40", "goal"]
    assert log[2][2] == [1, 40, 6]
    assert log[4][2] == [0, 11, 0]                             # start vertex reported
    assert 4.5 <= log[0][1] <= 5.5
    world.advance(10)
    assert "publish10" not in kinds(log)


def test_arrival_order_with_goal_wait():
    core, world, log = started(goal_wait=2.0)
    seq = core.seq
    core.on_goal_result(seq, True)
    world.advance(1.9)
    assert log == []                                          # still waiting on the vertex
    world.advance(0.2)
    assert kinds(log) == ["arrival", "decide", "publish11", "share", "publish40", "goal"]
    assert log[0][2] == 1 and log[2][2] == [0, 11, 1] and log[-1][2] == 2


def test_failed_goal_resent_three_times_then_strategy_chooses():
    core, world, log = started()
    target = core.target
    for k in range(MAX_RESENDS):
        core.on_goal_result(core.seq, False)
        assert kinds(log)[-2:] == ["backup", "clear"]
        world.advance(BACKUP_DURATION - 0.01)
        assert log[-1][0] == "clear"                          # not resent before the back-up
        world.advance(0.02)
        assert log[-1][0] == "goal" and log[-1][2] == target
    core.on_goal_result(core.seq, False)
    world.advance(BACKUP_DURATION + 0.01)
    assert kinds(log)[-2:] == ["failed", "goal"]
    assert log[-2][2] == target and log[-1][2] == 4
    assert "publish11" not in kinds(log) and "arrival" not in kinds(log)
    # the counter starts again for the new goal
    core.on_goal_result(core.seq, False)
    world.advance(BACKUP_DURATION + 0.01)
    assert log[-1][0] == "goal" and log[-1][2] == 4


def test_stale_and_cancelled_outcomes_are_ignored():
    core, world, log = started()
    old = core.seq
    core.redirect(3)                                          # new goal while moving
    assert log[-1] == ("goal", 0.0 + world.t, 3) and core.seq == old + 1
    core.on_goal_result(old, False)                           # the replaced goal's abort
    core.on_goal_result(old, True)
    world.advance(5)
    assert kinds(log) == ["goal"]


def test_interference_higher_id_pauses_and_resends():
    core, world, log = started(robot_id=1)
    world.t = 20.0                                            # past the first 10 s
    core.on_position(0, 5.0, 5.0)
    core.on_feedback(core.seq, 8.0, 5.0)                      # 3 m: no
    assert log == []
    target = core.target
    core.on_feedback(core.seq, 6.5, 5.5)                      # within 2 m
    assert kinds(log) == ["publish12", "cancel"] and log[0][2] == [1, 12]
    world.advance(INTERFERENCE_PAUSE - 0.01)
    assert len(log) == 2
    world.advance(0.02)
    assert log[-1][0] == "goal" and log[-1][2] == target and core.resends == 1
    core.on_feedback(core.seq, 5.0, 5.0)                      # < 10 s since: not again
    assert kinds(log).count("publish12") == 1
    world.advance(10.0)
    core.on_feedback(core.seq, 5.0, 5.0)
    assert kinds(log).count("publish12") == 2


def test_interference_lower_id_never_reacts_nor_in_first_10_s():
    core, world, log = started(robot_id=0)
    world.t = 30.0
    core.on_position(1, 0.0, 0.0)
    core.on_feedback(core.seq, 0.0, 0.0)
    assert log == []
    core1, world1, log1 = started(robot_id=1)
    world1.t = 9.0
    core1.on_position(0, 0.0, 0.0)
    core1.on_feedback(core1.seq, 0.0, 0.0)
    assert log1 == []


def test_interference_resends_count_towards_the_limit():
    core, world, log = started(robot_id=1)
    core.on_position(0, 0.0, 0.0)
    for k in range(MAX_RESENDS):
        world.advance(10.0)
        core.on_feedback(core.seq, 0.0, 0.0)
        world.advance(INTERFERENCE_PAUSE + 0.01)
    assert core.resends == MAX_RESENDS
    world.advance(10.0)
    core.on_feedback(core.seq, 0.0, 0.0)
    world.advance(INTERFERENCE_PAUSE + 0.01)
    assert log[-2][0] == "failed"


def test_communication_delay_and_loss():
    core, world, log = started(comm_delay=0.5)
    world.advance(1.0)                                        # the start's share goes out
    del log[:]
    t0 = world.t
    core.send([0, 41, 3, 9])
    core.send([0, 11, 3])                                     # visit reports never wait
    assert kinds(log) == ["publish11"]
    world.advance(0.49)
    assert len(log) == 1
    world.advance(0.02)
    assert log[-1][2] == [0, 41, 3, 9] and log[-1][1] == pytest.approx(t0 + 0.5, abs=0.02)

    def lost(seed):
        c, w, lg = make(loss=0.3)
        c.loss_rng.seed(seed)
        for _ in range(2000):
            c.send([0, 40, 1])
            c.send([0, 12])
        return c.messages_lost, kinds(lg).count("publish40"), kinds(lg).count("publish12")
    n_lost, n40, n12 = lost(5)
    assert n12 == 2000 and n_lost + n40 == 2000
    assert 0.25 < n_lost / 2000 < 0.35
    assert lost(5) == (n_lost, n40, n12)                      # seeded


def test_end_stops_everything():
    core, world, log = started(goal_wait=1.0)
    core.on_goal_result(core.seq, True)
    core.on_results(END)
    assert core.phase == "ended" and world.ended
    world.advance(10.0)
    assert "arrival" not in kinds(log) and "goal" not in kinds(log)
    core.on_results(GO)
    core.on_goal_result(core.seq, True)
    world.advance(10.0)
    assert "goal" not in kinds(log)


def test_redirect_dropped_while_waiting_on_a_vertex():
    core, world, log = started(goal_wait=2.0)
    core.on_goal_result(core.seq, True)
    core.redirect(4)
    world.advance(2.1)
    assert [e[2] for e in log if e[0] == "goal"] == [2]


def test_undecided_strategy_is_asked_again_and_reports_once():
    core, world, log = started()
    core.strategy.decide_none = 2
    t0 = world.t
    core.on_goal_result(core.seq, True)
    assert kinds(log) == ["arrival", "decide"] and core.state == "deciding"
    world.advance(0.49)
    assert len(log) == 2
    world.advance(0.6)
    assert kinds(log) == ["arrival", "decide", "decide", "decide", "publish11", "share",
                          "publish40", "goal"]
    assert log[4][1] == pytest.approx(t0 + 1.0)               # reported when decided


def test_redirect_while_deciding_is_the_decision():
    core, world, log = started()
    core.strategy.decide_none = 5
    core.on_goal_result(core.seq, True)
    core.redirect(4)
    assert kinds(log)[-4:] == ["publish11", "share", "publish40", "goal"]
    assert log[-1][2] == 4


def test_the_strategy_prepares_once_before_the_first_announcement():
    core, world, log = make()
    core.strategy.prepare = lambda v: log.append(("prepare", world.t, v))
    world.advance(3.0)
    core.ready()
    core.ready()                                # a second call changes nothing
    world.advance(2.5)
    assert kinds(log) == ["prepare", "publish10", "publish10"]
    assert log[0] == ("prepare", 3.0, 0)
    core.on_results(GO)
    world.advance(1.0)
    assert kinds(log).count("prepare") == 1 and "start" in kinds(log)
