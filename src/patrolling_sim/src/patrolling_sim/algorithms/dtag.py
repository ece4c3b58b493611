"""DTAG, DTA-Greedy (``DTAGreedy``; Farinelli, Iocchi, Nardi, Autonomous Robots 41(6), 2017).

Each robot keeps a global idleness estimate ``gi`` (100 s for every vertex at start, ageing
with time, merged with teammates' estimates by taking the minimum). On reaching u it sets
``gi[u] = 0`` and picks the first maximum over v != u of

    theta_idleness * gi[v] + theta_navigation * pathcost(u, v) [px]
        + theta_distance_from_origin * |origin - v| [m]

(origin = the robot's start position), parameters from ``params/DTA/DTAGreedy.params``
(1, -0.75, -5). It then broadcasts ``[id, 40, I_0..I_{V-1}, next]`` with its own next goal's
entry as 0. If a teammate announces the same next goal, the robot with the higher id yields:
it treats that vertex as visited, recomputes and redirects.
"""
import numpy as np

from .base import MSG_DTA_IDLENESS, PatrolStrategy, register
from .dta_common import IdlenessEstimate, decode_idleness, dta_params

DEFAULTS = {"theta_idleness": 1.0, "theta_navigation": -0.75,
            "theta_distance_from_origin": -5.0}


@register
class DTAGreedy(PatrolStrategy):
    name = "DTAG"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.p = dta_params(ctx, "DTAGreedy", DEFAULTS)
        self.algorithm_params = ",".join(f"{self.p[k]:g}" for k in DEFAULTS)
        self.gi = None
        self.origin = ctx.start_position
        self._origin_dist = None

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.gi = IdlenessEstimate(self.graph.n, 100.0, now)
        self.gi.values[start_vertex] = 0.0
        if self.origin is None:
            self.origin = tuple(self.graph.pos[start_vertex])

    def on_arrival(self, vertex, now):
        super().on_arrival(vertex, now)
        self.gi.advance(now)[vertex] = 0.0

    def utility(self, u, g):
        """Utility of every vertex as a goal from u (numpy array)."""
        p = self.p
        if self._origin_dist is None:
            self._origin_dist = np.hypot(self.graph.pos[:, 0] - self.origin[0],
                                         self.graph.pos[:, 1] - self.origin[1])
        return (p["theta_idleness"] * g + p["theta_navigation"] * self.graph.dist[u]
                + p["theta_distance_from_origin"] * self._origin_dist)

    def choose_next(self, now, exclude=()):
        u = self.current
        score = self.utility(u, self.gi.advance(now))
        score[~np.isfinite(self.graph.dist[u])] = -np.inf
        score[u] = -np.inf
        for v in exclude:
            score[v] = -np.inf
        if not np.isfinite(score).any():
            return u
        return int(np.argmax(score))        # first maximum, as the original

    def next_vertex(self, now):
        v = super().next_vertex(now)
        self.send(MSG_DTA_IDLENESS, *self.gi.encode(now, zero=v), v)
        return v

    def on_message(self, data, now):
        dec = decode_idleness(data, self.graph.n)
        if dec is None or self.gi is None:
            return
        values, their_next = dec
        self.gi.merge(values, now)
        if their_next == self.next and self.next is not None and self.id > data[0]:
            taken = self.next
            self.gi.values[taken] = 0.0
            self.next = self.choose_next(now, exclude=(taken,))
            self.driver.redirect(self.next)
