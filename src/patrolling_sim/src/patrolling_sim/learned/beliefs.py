"""What each robot of a team believes, one row per robot (docs/learning.md, "Beliefs"): the
tables the observations read, in the learning environment and in the ``POLICY`` strategy.

- ``last_visit[i, v]`` (numpy): latest time robot i visited v or heard of a visit of v;
- ``mate_vertex[i][j]``, ``mate_next[i][j]``, ``mate_time[i][j]`` (lists, read one entry at
  a time): the vertex teammate j last reported, the vertex it said it heads to, and when i
  heard it (its start vertex at time 0 until it reports when the start vertices are known
  to the team, else -1: unknown);
- ``current[i]``: the vertex robot i last reached.

The tables are changed in place, never rebound (the observation code keeps views of their
rows). Beliefs change only through the robot's own visits (:meth:`TeamBeliefs.start`,
:meth:`TeamBeliefs.arrive`) and the ``[j, MSG_LEARNED_VISIT, v, next]`` messages actually
delivered to it under the run's communication model (:meth:`TeamBeliefs.news`).
"""
import numpy as np


class TeamBeliefs:
    """Every robot's beliefs (module docstring). ``start_vertices``: the team's start
    vertices, or None when the team does not know them (teammates then start unknown,
    -1, until they report); ``robots`` and ``n_vertices`` size the tables."""

    def __init__(self, robots: int, n_vertices: int, start_vertices=None):
        self.last_visit = np.zeros((robots, n_vertices))
        # each row as a memoryview: scalar reads and writes without numpy's per-call cost
        self._lv = [memoryview(row) for row in self.last_visit]
        if start_vertices is None:
            starts = [-1] * robots
        else:
            starts = [int(v) for v in start_vertices]
        self.mate_vertex = [list(starts) for _ in range(robots)]
        self.mate_next = [list(starts) for _ in range(robots)]
        self.mate_time = [[0.0] * robots for _ in range(robots)]
        self.current = list(starts)
        #: told of every belief change (an incremental observation builder, with the
        #: methods ``rebuild(i)``, ``news(i, j, v, nxt, now, fresher)`` and optionally
        #: ``receiver(i)``, see :meth:`receiver`), or None
        self.listener = None

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

    def receiver(self, i: int):
        """A function ``f(j, v, nxt, now)`` that does ``news(i, j, v, nxt, now)`` for robot
        ``i`` (the listener's fused one when it has one: one call per delivered message)."""
        fused = getattr(self.listener, "receiver", None)
        if fused is not None:
            return fused(i)
        return lambda j, v, nxt, now: self.news(i, j, v, nxt, now)

    def news(self, i: int, j: int, v: int, nxt: int, now: float) -> None:
        """Robot ``i`` heard at ``now`` that teammate ``j`` reached ``v``, heading to ``nxt``
        (the listener is told with ``fresher``: whether the believed visit time of v
        changed)."""
        row = self._lv[i]
        fresher = now > row[v]
        if fresher:
            row[v] = now
        self.mate_vertex[i][j] = v
        self.mate_next[i][j] = nxt
        self.mate_time[i][j] = now
        if self.listener is not None:
            self.listener.news(i, j, v, nxt, now, fresher)
