"""One robot's PatrolAgent life cycle, free of ROS: the single implementation that both the
ROS agent node (:mod:`patrolling_sim.ros.agent`) and the graph-level simulator
(:mod:`patrolling_sim.graphsim.simulator`) drive (both build it with
:func:`patrolling_sim.agent.factory.build_agent`). The life cycle, its order of events, the
messages and the timing constants are described in ``docs/protocol.md``.

The core is a state machine. Its driver feeds it events (``ready``, ``on_results``,
``on_position``, ``on_goal_result``, ``on_feedback``, ``shutdown``) and the core acts on the
world only through an :class:`Effects` object the driver implements (send a navigation goal,
cancel it, publish on ``/results``, run a timer, back up, clear costmaps). The core also is
the :class:`~patrolling_sim.algorithms.base.Driver` its strategy sees: strategy messages go
through the core's communication delay and loss, strategy timers through the core's timer.

Phases: ``init`` (waiting for the navigation server) -> ``ready`` (announcing ``[id,10,1]``
every 2 s) -> ``starting`` (GO received, random start delay) -> ``patrol`` -> ``ended``.
Within ``patrol`` the robot is ``moving`` (a goal is active), ``waiting`` (goal wait at a
reached vertex), ``deciding`` (the strategy has not chosen yet, asked again every 0.5 s),
``paused`` (interference) or ``backing_up`` (after a failed goal).

Not thread safe: a multi-threaded driver (rospy) calls it under one lock.
"""
import random
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from patrolling_sim.agent.faults import MIN_COMM_DELAY, ScenarioMixin
from patrolling_sim.algorithms.base import MSG_FAILURE, Driver, PatrolStrategy
from patrolling_sim.common.protocol import (END, GO, MONITOR_ID, MSG_INIT, MSG_INTERFERENCE,
                                            MSG_TARGET_REACHED, START_DELAY_MAX)

ANNOUNCE_PERIOD = 2.0          # s between two [id,10,1] announcements
MAX_RESENDS = 3                # resends of the same goal before strategy.on_goal_failed
BACKUP_DURATION = 1.0          # s the back-up manoeuvre takes before the goal is resent
INTERFERENCE_DIST = 2.0        # m
INTERFERENCE_PERIOD = 10.0     # s: at most one detection per period
INTERFERENCE_PAUSE = 3.0       # s stopped after a detection
DECISION_RETRY = 0.5           # s between two questions to a strategy that has not decided
#: message types that are never delayed nor lost (start-up, visit report, interference)
IMMEDIATE_TYPES = (MSG_INIT, MSG_TARGET_REACHED, MSG_INTERFERENCE, MSG_FAILURE)
#: first message type of the algorithms' own messages
FIRST_ALGORITHM_TYPE = 30


class Effects:
    """What the core asks of the world. Each driver implements every method."""

    def now(self) -> float:
        """Current time (s): ROS time, or the simulator's clock."""
        raise NotImplementedError

    def publish(self, data: List[int]) -> None:
        """Put ``data`` on ``/results`` now (no delay, no loss: the core applied them)."""
        raise NotImplementedError

    def send_goal(self, vertex: int, seq: int) -> None:
        """Start navigating to ``vertex``, replacing any active goal (whose outcome must then
        not be reported). Report the outcome with ``core.on_goal_result(seq, succeeded)`` and
        positions on the way with ``core.on_feedback(seq, x, y)``."""
        raise NotImplementedError

    def cancel_goal(self) -> None:
        """Stop navigating (a self-cancel: no outcome is reported for that goal)."""
        raise NotImplementedError

    def call_later(self, delay: float, fn: Callable[[], None]) -> None:
        """Run ``fn()`` once after ``delay`` s, without blocking."""
        raise NotImplementedError

    def backup(self) -> None:
        """The short back-up manoeuvre after a failed goal (reverse, then rotate)."""
        raise NotImplementedError

    def clear_costmaps(self) -> None:
        """Ask navigation to clear its costmaps (at start and after a failed goal)."""
        raise NotImplementedError

    def end(self) -> None:
        """The monitor's END arrived; the core has stopped. Default: nothing."""

    def log(self, text: str) -> None:
        """An informational line about this robot. Default: nothing."""


class PatrolAgentCore(ScenarioMixin, Driver):
    """The life cycle of robot ``robot_id`` around a strategy. See the module docstring.

    Args:
        effects: the driver's :class:`Effects`.
        robot_id: own index 0..N-1.
        start_vertex: the vertex the robot starts on.
        strategy_factory: ``f(driver) -> PatrolStrategy``; called once with this core.
        seed: seeds the message-loss and start-delay generators (separate from the
            strategy's own generator, so that they never perturb decisions).
        goal_wait, comm_delay, loss: ``/goal_reached_wait``, ``/communication_delay``,
            ``/lost_message_rate``.
        comm, positions, silence_check: the scenario (:mod:`patrolling_sim.agent.faults`):
            the receiver's communication model (None: perfect), the true positions for the
            range model, and whether silent teammates are reported to the strategy.
    """

    def __init__(self, effects: Effects, robot_id: int, start_vertex: int,
                 strategy_factory: Callable[[Driver], PatrolStrategy], seed: int = 0,
                 goal_wait: float = 0.0, comm_delay: float = 0.0, loss: float = 0.0,
                 comm=None, positions=None, silence_check: bool = False):
        self.fx = effects
        self.id = int(robot_id)
        self.start_vertex = int(start_vertex)
        self.goal_wait = float(goal_wait)
        self.comm_delay = float(comm_delay)
        self.loss = float(loss)
        self.loss_rng = random.Random(seed * 7919 + 1)
        self.jitter_rng = random.Random(seed * 7919 + 2)
        self.phase = "init"
        self.state = None
        self.started = False
        self.pending_msgs: List[Tuple[int, ...]] = []   # algorithm messages, GO to start
        self.target: Optional[int] = None         # vertex of the current (or paused) goal
        self.seq = 0                # goal sequence number: stale outcomes/timers are ignored
        self.resends = 0
        self._report: Optional[int] = None        # visit to report once a decision is made
        #: last known position of each teammate (robot id -> (x, y) m); a driver may share
        #: one table among all its cores
        self.team_pos: Dict[int, Tuple[float, float]] = {}
        self.own_pos: Optional[Tuple[float, float]] = None
        self.last_interference = 0.0
        self.interferences = 0
        self.messages_sent = 0
        self.messages_lost = 0
        self._init_scenario(comm, positions, silence_check)
        self.strategy = strategy_factory(self)

    # -- Driver: what the strategy sees ----------------------------------------------------
    def now(self) -> float:
        return self.fx.now()

    def send(self, data: List[int]) -> None:
        """Broadcast ``data`` on /results: types 10/11/12 at once; algorithm messages are
        lost with probability ``loss`` and published ``comm_delay`` s later."""
        if self.failed:
            return
        data = [int(x) for x in data]
        if len(data) > 1 and data[1] in IMMEDIATE_TYPES:
            self.fx.publish(data)
            return
        self.messages_sent += 1
        if self.loss > 0 and self.loss_rng.random() < self.loss:
            self.messages_lost += 1
            return
        if self.comm_delay > MIN_COMM_DELAY:
            self._later(self.comm_delay, lambda: self.fx.publish(data))
        else:
            self.fx.publish(data)

    def call_later(self, delay: float, fn: Callable[[], None]) -> None:
        self._later(delay, fn)

    def redirect(self, vertex: int) -> None:
        """Abandon the current goal and head to ``vertex`` (e.g. DTAG's conflict rule). While
        the robot waits on a reached vertex the request is dropped: the decision that ends
        the wait supersedes it."""
        if self.phase != "patrol":
            return
        if self.state == "deciding":
            self._decided(int(vertex))
        elif self.state in ("moving", "paused", "backing_up"):
            self.resends = 0
            self._send_goal(int(vertex))

    # -- events from the driver ----------------------------------------------------------
    def ready(self) -> None:
        """The navigation server is up: let the strategy prepare (its route, before GO), then
        announce ``[id,10,1]`` now and every 2 s until GO."""
        if self.phase == "init":
            self.strategy.prepare(self.start_vertex)
            self.phase = "ready"
            self._announce()

    def on_results(self, data: List[int]) -> None:
        """A message on /results (own messages are ignored here)."""
        if len(data) < 2 or data[0] == self.id:
            return
        if self.failed and not (data[0] == MONITOR_ID and len(data) > 2 and data[2] == END):
            self._counts["ignored_failed"] += 1
            return
        if data[0] == MONITOR_ID and data[1] == MSG_INIT:
            if len(data) > 2 and data[2] == GO and self.phase in ("init", "ready"):
                self.phase = "starting"
                delay = self.jitter_rng.uniform(0.0, START_DELAY_MAX)
                self.fx.log(f"robot {self.id}: GO received, starting in {delay:.2f} s")
                self._later(delay, self._begin)
            elif len(data) > 2 and data[2] == END and self.phase != "ended":
                self.fx.log(f"robot {self.id}: END received from the monitor")
                self.shutdown()
                self.fx.end()
            return
        if data[1] >= FIRST_ALGORITHM_TYPE and self.phase in ("starting", "patrol"):
            if self.comm is None:
                self.hear(data, self.fx.now())
                return
            # the strategy gets a tuple (_hand_over): no one changes a published message
            self._receive_results(data, self._deliver)

    def hear(self, data: Sequence[int], now: float) -> None:
        """An algorithm message (type >= FIRST_ALGORITHM_TYPE) from another robot over
        perfect links (no communication model), at time ``now``: what :meth:`on_results`
        does with it, in one call. Delivered at once, without the model's call: a team of 12
        hears each message 11 times, so graph mode's broadcast calls this directly."""
        if data[0] == self.id:
            return
        if self.failed:
            self._counts["ignored_failed"] += 1
            return
        if self.phase in ("starting", "patrol"):
            self._perfect_results += 1
            self._hand_over(data, now)

    def _deliver(self, data: Sequence[int], now: Optional[float] = None) -> None:
        """An algorithm message the communication model let through (possibly late);
        ``now``: the clock, if the caller has read it."""
        if self.phase in ("starting", "patrol") and not self.failed:
            self._hand_over(data, self.fx.now() if now is None else now)

    def _hand_over(self, data: Sequence[int], now: float) -> None:
        """A delivered algorithm message to the strategy (or kept until it starts), as a
        tuple: read-only, so one tuple can reach every receiver without a copy each (graph
        mode's broadcast hands all of them the same one)."""
        self.heard(data[0], now)
        if type(data) is not tuple:
            data = tuple(data)
        if self.started:
            self.strategy.on_message(data, now)
        else:
            self.pending_msgs.append(data)

    def on_position(self, robot_id: int, x: float, y: float) -> None:
        """A teammate's position (from /positions)."""
        if robot_id != self.id and not self.failed:
            self._receive_position(robot_id, x, y)

    def on_feedback(self, seq: int, x: float, y: float) -> None:
        """Own position while goal ``seq`` is active: evaluate interference (only robots with
        a lower id are checked, so of two close robots only the higher id reacts)."""
        if self.failed:
            return
        self.own_pos = (x, y)
        if seq != self.seq or self.phase != "patrol" or self.state != "moving":
            return
        now = self.fx.now()
        if now - self.last_interference < INTERFERENCE_PERIOD:
            return
        d2 = INTERFERENCE_DIST * INTERFERENCE_DIST
        get = self.team_pos.get
        for j in range(self.id):
            p = get(j)
            if p is not None and (p[0] - x) ** 2 + (p[1] - y) ** 2 <= d2:
                self._interference(j, now)
                return

    def on_goal_result(self, seq: int, succeeded: bool) -> None:
        """Outcome of goal ``seq``: reached, or failed (aborted/rejected/lost by navigation)."""
        if seq != self.seq or self.phase != "patrol" or self.state != "moving" or self.failed:
            return
        if succeeded:
            self.state = "waiting"
            if self.goal_wait > 0:
                self._later(self.goal_wait, lambda: self._arrived(seq))
            else:
                self._arrived(seq)
            return
        self.fx.log(f"robot {self.id}: goal to vertex {self.target} failed")
        self.state = "backing_up"
        self.fx.backup()
        self.fx.clear_costmaps()
        self._later(BACKUP_DURATION, lambda: self._resend(seq))

    def shutdown(self) -> None:
        """Stop: cancel the active goal; every pending timer becomes a no-op."""
        if self.phase == "ended":
            return
        moving = self.phase == "patrol" and self.state == "moving"
        self.phase = "ended"
        self.seq += 1
        if moving:
            self.fx.cancel_goal()

    # -- life cycle ------------------------------------------------------------------------
    def _later(self, delay, fn):
        life = self.life

        def fire():
            if self.phase != "ended" and life == self.life:
                fn()
        self.fx.call_later(max(0.0, float(delay)), fire)

    def _announce(self):
        if self.phase == "ready":
            self.fx.publish([self.id, MSG_INIT, 1])
            self._later(ANNOUNCE_PERIOD, self._announce)

    def _begin(self):
        """End of the start delay: clear costmaps, start the strategy, apply what was heard
        since GO, then decide and report the start vertex."""
        if self.phase != "starting":
            return
        now = self.fx.now()
        self.fx.clear_costmaps()
        self.strategy.start(self.start_vertex, now)
        self.started = True
        self.phase = "patrol"
        pending, self.pending_msgs = self.pending_msgs, []
        for data in pending:
            self.strategy.on_message(data, now)
        self.target = self.start_vertex
        self._start_silence_check(now)
        self._decide(self.start_vertex)

    def _arrived(self, seq):
        """End of the goal wait: update the strategy, decide, report, share, go."""
        if seq != self.seq or self.phase != "patrol" or self.state != "waiting":
            return
        self.strategy.on_arrival(self.target, self.fx.now())
        self._decide(self.target)

    def _decide(self, report):
        """Ask the strategy for the next goal; once it has one: report the visit ``report``
        (None: nothing to report), let the strategy share, send the goal."""
        self._report = report
        v = self.strategy.next_vertex(self.fx.now())
        if v is None:
            self.state = "deciding"
            seq = self.seq
            self._later(DECISION_RETRY, lambda: self._retry_decision(seq))
            return
        self._decided(int(v))

    def _retry_decision(self, seq):
        if seq == self.seq and self.phase == "patrol" and self.state == "deciding":
            self._decide(self._report)

    def _decided(self, v):
        report, self._report = self._report, None
        if report is not None:
            self.fx.publish([self.id, MSG_TARGET_REACHED, int(report)])
            self.strategy.send_results(self.fx.now())
        self.resends = 0
        self._send_goal(v)

    def _send_goal(self, v):
        self.seq += 1
        self.target = int(v)
        self.state = "moving"
        self.fx.send_goal(self.target, self.seq)

    def _resend(self, seq):
        """After a back-up or an interference pause: resend the same goal, or after
        ``MAX_RESENDS`` resends in a row give up on it (strategy.on_goal_failed)."""
        if (seq != self.seq or self.phase != "patrol"
                or self.state not in ("backing_up", "paused")):
            return
        if self.resends < MAX_RESENDS:
            self.resends += 1
            self.fx.log(f"robot {self.id}: resending goal {self.target} "
                        f"({self.resends}/{MAX_RESENDS})")
            self._send_goal(self.target)
            return
        self.resends = 0
        failed = self.target
        v = self.strategy.on_goal_failed(failed, self.fx.now())
        self.fx.log(f"robot {self.id}: giving up on vertex {failed}, going to {v}")
        if v is None:
            self._decide(None)
        else:
            self._send_goal(int(v))

    def _interference(self, other, now):
        """Report ``[id,12]``, stop for 3 s, then resend the same goal (a resend as after a
        failure: it counts towards ``MAX_RESENDS``)."""
        self.last_interference = now
        self.interferences += 1
        self.fx.log(f"robot {self.id}: interference with robot {other}")
        self.fx.publish([self.id, MSG_INTERFERENCE])
        self.seq += 1
        self.fx.cancel_goal()
        self.state = "paused"
        seq = self.seq
        self._later(INTERFERENCE_PAUSE, lambda: self._resend(seq))
