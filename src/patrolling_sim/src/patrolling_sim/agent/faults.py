"""The scenario side of a robot's life cycle (``docs/scenarios.md``): the communication model
applied at the receiver, failure and repair, and the teammate-silence check. A mixin of
:class:`~patrolling_sim.agent.core.PatrolAgentCore`, kept in its own module so that the
life cycle proper stays readable; with perfect communication, no failure and no silence
check it changes nothing (the fidelity and graph-mode tests pin that).

Receiver side: a broadcast on ``/results`` or ``/positions`` is one publication, so the
per-link decision (``comm.link(sender, receiver, t, positions)``) is taken where each robot
receives it. The range model needs the *true* positions of both ends: the core keeps every
position it receives, before the model drops it, in ``true_pos`` (plus its own from the
navigation feedback); a driver that knows better (graph mode) passes ``positions``.
"""
from typing import Callable, Dict, List, Optional, Tuple

from patrolling_sim.algorithms.base import MSG_FAILURE
from patrolling_sim.scenarios.comm import CommModel, parse_comm

#: s between two teammate-silence checks
#: s: smaller communication delays are not applied (delivered at once); agent_core uses it
#: too (defined here, imported there: agent_core imports this module)
MIN_COMM_DELAY = 0.001
SILENCE_CHECK_PERIOD = 10.0
#: what comm_counters() reports (this robot as the receiver)
COUNTER_KEYS = ("sent", "delivered", "lost", "results_sent", "results_delivered",
                "results_lost", "positions_sent", "positions_delivered", "positions_lost",
                "sender_lost", "ignored_failed")


def make_comm(comm, seed: int, occupancy=None) -> Optional[CommModel]:
    """The receiver's model for ``comm`` (a spec string or a model): None for perfect
    communication (the core then takes its original code path). A spec is seeded with
    ``seed * 7919 + 3`` (``seed``: the agent's seed), apart from the other generators."""
    if comm is None or isinstance(comm, CommModel):
        return None if comm is None or type(comm) is CommModel and \
            comm.delay.kind == "none" else comm
    spec = str(comm).strip().lower()
    if spec in ("", "perfect", "none"):
        return None
    model = parse_comm(comm, seed=seed * 7919 + 3, occupancy=occupancy)
    if type(model) is CommModel and model.delay.kind == "none":
        return None
    return model


class ScenarioMixin:
    """Failure, repair, communication model and teammate silence (module docstring).
    Expects ``self.fx``, ``self.id``, ``self.phase``, ``self.state``, ``self.strategy``,
    ``self.team_pos``, ``self.own_pos`` and the life-cycle methods of the core."""

    def _init_scenario(self, comm: Optional[CommModel],
                       positions: Optional[Callable[[int], Optional[Tuple[float, float]]]],
                       silence_check: bool) -> None:
        self.comm = comm
        self.failed = False
        self.life = 0                   # bumps on failure: the timers of a past life are void
        #: every position heard, before the model (the range model's truth in ROS mode)
        self.true_pos: Dict[int, Tuple[float, float]] = {}
        self._positions = positions or self._true_position
        self.silence_check = bool(silence_check)
        self.last_heard: Dict[int, float] = {}
        self.silent: set = set()
        self._counts = dict.fromkeys(COUNTER_KEYS, 0)
        #: algorithm messages received without a model (each: sent and delivered)
        self._perfect_results = 0

    # -- receiving through the model ----------------------------------------------------------
    def _true_position(self, robot: int):
        if robot == self.id:
            return self.own_pos
        return self.true_pos.get(robot)

    def _link(self, kind: str, sender: int) -> Optional[float]:
        """The model's verdict on one message of ``kind`` (results | positions)."""
        c = self._counts
        c["sent"] += 1
        c[kind + "_sent"] += 1
        d = self.comm.link(sender, self.id, self.fx.now(), self._positions)
        if d is None:
            c["lost"] += 1
            c[kind + "_lost"] += 1
        else:
            c["delivered"] += 1
            c[kind + "_delivered"] += 1
        return d

    def _receive_results(self, data: List[int], deliver: Callable[[List[int]], None]) -> None:
        if self.comm is None:
            self._perfect_results += 1            # counted in comm_counters()
            deliver(data)
            return
        d = self._link("results", int(data[0]))
        if d is None:
            return
        if d > MIN_COMM_DELAY:
            self._later(d, lambda: deliver(data))
        else:
            deliver(data)

    def _receive_position(self, robot: int, x: float, y: float) -> None:
        self.true_pos[robot] = (x, y)
        if self.comm is None:
            self.team_pos[robot] = (x, y)
            return
        d = self._link("positions", robot)
        if d is None:
            return
        if d > MIN_COMM_DELAY:
            def late():
                self.team_pos[robot] = (x, y)
            self._later(d, late)
        else:
            self.team_pos[robot] = (x, y)

    def heard(self, robot: int, now: float) -> None:
        """A teammate's algorithm message was delivered (teammate-silence bookkeeping)."""
        self.last_heard[robot] = now
        if self.silent:
            self.silent.discard(robot)

    def comm_counters(self) -> Dict[str, int]:
        """Messages this robot received through the model (see :data:`COUNTER_KEYS`);
        ``sender_lost`` counts its own algorithm messages lost by the old ``--loss`` rate."""
        out = dict(self._counts)
        for key in ("sent", "delivered", "results_sent", "results_delivered"):
            out[key] += self._perfect_results
        out["sender_lost"] = self.messages_lost
        return out

    # -- failure and repair -------------------------------------------------------------------
    def fail(self) -> None:
        """The robot fails: it reports ``[id,13,0]`` (the scenario speaks for it), stops
        moving where it is, and from now on neither decides nor communicates; every timer
        it had running is void. Ignored if already failed or ended."""
        if self.failed or self.phase == "ended":
            return
        self.fx.publish([self.id, MSG_FAILURE, 0])
        moving = self.phase == "patrol" and self.state in ("moving",)
        self.failed = True
        self.life += 1
        self.seq += 1
        if moving:
            self.fx.cancel_goal()
        self.fx.log(f"robot {self.id}: failed")

    def repair(self) -> None:
        """The robot is back: it reports ``[id,13,1]`` and decides again from the last vertex
        it reached (a robot that failed before its start delay ended starts now)."""
        if not self.failed or self.phase == "ended":
            return
        self.failed = False
        self.fx.publish([self.id, MSG_FAILURE, 1])
        self.fx.log(f"robot {self.id}: repaired")
        if self.phase == "starting":
            self._later(0.0, self._begin)
        elif self.phase == "patrol":
            now = self.fx.now()
            self.strategy.on_repair(now)
            self._decide(None)
            self.last_heard = dict.fromkeys(self.last_heard, now)
            self.silent.clear()
            if self.silence_check:
                self._later(SILENCE_CHECK_PERIOD, self._check_silence)

    # -- teammate silence ---------------------------------------------------------------------
    def _start_silence_check(self, now: float) -> None:
        if not self.silence_check:
            return
        for r in range(self.strategy.ctx.team_size):
            if r != self.id:
                self.last_heard.setdefault(r, now)
        self._later(SILENCE_CHECK_PERIOD, self._check_silence)

    def _check_silence(self) -> None:
        """Every teammate not heard for the strategy's ``teammate_timeout`` s is reported once
        to ``strategy.on_teammate_silent`` (until it is heard again)."""
        now = self.fx.now()
        timeout = self.strategy.teammate_timeout
        for r in sorted(self.last_heard):
            if r not in self.silent and now - self.last_heard[r] >= timeout:
                self.silent.add(r)
                self.fx.log(f"robot {self.id}: teammate {r} silent for {timeout:g} s")
                self.strategy.on_teammate_silent(r, now)
        self._later(SILENCE_CHECK_PERIOD, self._check_silence)
