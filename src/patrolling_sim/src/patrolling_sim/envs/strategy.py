"""The robots' decision maker inside the learning environment (:mod:`patrolling_sim.envs`):
a :class:`~patrolling_sim.algorithms.base.PatrolStrategy` that never decides by itself.

When the life cycle asks it for the next vertex it writes its robot's id on the
:class:`DecisionBoard` and answers None ("not decided yet"): the environment stops the
simulation there, hands the decision to the policy, and applies it with the life cycle's
``redirect`` at the same simulated time (docs/learning.md, "Timing").

What the robots believe is kept in the board's tables
(:class:`~patrolling_sim.learned.beliefs.TeamBeliefs`, one row per robot), where the
environment's observations read it; the ``POLICY`` strategy keeps the same tables for its
own robot. Beliefs change only through the robot's own visits and the
``[j, MSG_LEARNED_VISIT, v, next]`` messages actually delivered to it under the run's
communication model.
"""
from typing import List

from patrolling_sim.algorithms.base import PatrolStrategy
from patrolling_sim.common.protocol import MSG_LEARNED_VISIT
from patrolling_sim.learned.beliefs import TeamBeliefs

#: key of the :class:`DecisionBoard` in the strategy's params
BOARD_PARAM = "decision_board"


class DecisionBoard(TeamBeliefs):
    """The robots waiting for a decision, in the order they asked (``pending``), and every
    robot's beliefs (:class:`~patrolling_sim.learned.beliefs.TeamBeliefs`). One per
    episode."""

    def __init__(self, robots: int, n_vertices: int, start_vertices):
        super().__init__(robots, n_vertices, start_vertices)
        self.pending: List[int] = []

    def has_pending(self) -> bool:
        """True while some robot waits for a decision (the simulator's stop condition)."""
        return bool(self.pending)


class EnvStrategy(PatrolStrategy):
    """Decisions come from the environment (module docstring). Not registered: the
    environment hands it to the simulator as ``strategy_class``."""

    name = "ENV"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.board: DecisionBoard = ctx.params[BOARD_PARAM]
        self._news = self.board.receiver(self.id)

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
            self._news(data[0], data[2], data[3], now)

    def on_goal_failed(self, vertex, now):
        """A goal given up: the environment decides again (the life cycle asks)."""
        return None
