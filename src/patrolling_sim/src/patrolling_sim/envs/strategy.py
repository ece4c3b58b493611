"""The robots' decision maker inside the learning environment (:mod:`patrolling_sim.envs`):
a :class:`~patrolling_sim.algorithms.base.PatrolStrategy` that never decides by itself.

When the life cycle asks it for the next vertex it writes its robot's id on the
:class:`DecisionBoard` and answers None ("not decided yet"): the environment stops the
simulation there, hands the decision to the policy, and applies it with the life cycle's
``redirect`` at the same simulated time (docs/learning.md, "Timing").

What the robot believes is kept in the board's tables, one row per robot, where the
environment's observations read it (``current[i]``: the vertex robot i last reached):

- ``last_visit[i, v]`` (numpy): latest time robot i visited v or heard of a visit of v;
- ``mate_vertex[i][j]``, ``mate_next[i][j]``, ``mate_time[i][j]`` (lists, read one entry at
  a time): the vertex teammate j
  last reported, the vertex it said it heads to, and when i heard it (its start vertex at
  time 0 until it reports: the start vertices are known to the team).

Beliefs change only through the robot's own visits and the ``[j, MSG_LEARNED_VISIT, v, next]``
messages actually delivered to it under the run's communication model.
"""
from typing import List

import numpy as np

from patrolling_sim.algorithms.base import PatrolStrategy
from patrolling_sim.common.protocol import MSG_LEARNED_VISIT

#: key of the :class:`DecisionBoard` in the strategy's params
BOARD_PARAM = "decision_board"


class DecisionBoard:
    """The robots waiting for a decision, in the order they asked, and every robot's beliefs
    (module docstring). One per episode."""

    def __init__(self, robots: int, n_vertices: int, start_vertices):
        self.pending: List[int] = []
        self.last_visit = np.zeros((robots, n_vertices))
        starts = [int(v) for v in start_vertices]
        self.mate_vertex = [list(starts) for _ in range(robots)]
        self.mate_next = [list(starts) for _ in range(robots)]
        self.mate_time = [[0.0] * robots for _ in range(robots)]
        self.current = list(starts)
        #: told of every belief change (observe.FlatObservations), or None
        self.listener = None

    def has_pending(self) -> bool:
        """True while some robot waits for a decision (the simulator's stop condition)."""
        return bool(self.pending)

    def start(self, i: int, v: int) -> None:
        """Robot ``i`` starts on ``v``: as every strategy, it takes v as visited at 0.1 and
        every other vertex at 0."""
        self.last_visit[i] = 0.0
        self.last_visit[i, v] = 0.1
        self.current[i] = v
        if self.listener is not None:
            self.listener.rebuild(i)

    def arrive(self, i: int, v: int, now: float) -> None:
        """Robot ``i`` reached ``v`` at ``now``."""
        self.current[i] = v
        self.last_visit[i, v] = now
        if self.listener is not None:
            self.listener.rebuild(i)

    def news(self, i: int, j: int, v: int, nxt: int, now: float) -> None:
        """Robot ``i`` heard at ``now`` that teammate ``j`` reached ``v``, heading to ``nxt``."""
        listener = self.listener
        if now > self.last_visit[i, v]:
            self.last_visit[i, v] = now
            if listener is not None:
                listener.belief(i, v, now)
        self.mate_vertex[i][j] = v
        self.mate_next[i][j] = nxt
        self.mate_time[i][j] = now
        if listener is not None:
            listener.news(i, j, v, nxt, now)


class EnvStrategy(PatrolStrategy):
    """Decisions come from the environment (module docstring). Not registered: the
    environment hands it to the simulator as ``strategy_class``."""

    name = "ENV"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.board: DecisionBoard = ctx.params[BOARD_PARAM]

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.board.start(self.id, start_vertex)

    def next_vertex(self, now):
        """Ask the environment: the decision arrives through the life cycle's redirect."""
        self.board.pending.append(self.id)
        return None

    def choose_next(self, now):
        return None

    def on_arrival(self, vertex, now):
        self.current = vertex
        self.board.arrive(self.id, vertex, now)

    def send_results(self, now):
        """Tell the teammates the visit and the next goal (through the communication model)."""
        if self.next is not None:
            self.send(MSG_LEARNED_VISIT, self.current, self.next)

    def on_message(self, data, now):
        if len(data) >= 4 and data[1] == MSG_LEARNED_VISIT:
            self.board.news(self.id, data[0], data[2], data[3], now)

    def on_goal_failed(self, vertex, now):
        """A goal given up: the environment decides again (the life cycle asks)."""
        return None
