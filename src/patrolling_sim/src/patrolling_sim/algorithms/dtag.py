"""DTAG, DTA-Greedy (``DTAGreedy``; Farinelli, Iocchi, Nardi, Autonomous Robots 41(6), 2017).

Each robot keeps a global idleness estimate ``gi`` (100 s for every vertex at start, ageing
with time, merged with teammates' estimates by taking the minimum). On reaching u it sets
``gi[u] = 0`` and picks the first maximum over v != u of

    theta_idleness * gi[v] + theta_navigation * pathcost(u, v) [px]
        + theta_distance_from_origin * ``|origin - v|`` [m]

(origin = the robot's start position), parameters from ``params/DTA/DTAGreedy.params``
(1, -0.75, -5). It then broadcasts ``[id, 40, I_0..I_{V-1}, next]`` with its own next goal's
entry as 0. Conflict rule, as the original: a robot that receives a teammate's message whose
``next`` equals its own next goal gives that goal up -- whatever the ids, so when the two
messages cross both robots yield -- pretends it has reached the contested vertex (its
current vertex becomes that vertex, not reported to the monitor, no message sent), re-plans
from it (path costs from the contested vertex) and heads to the new goal.
"""
import numpy as np

from patrolling_sim.algorithms.base import PatrolStrategy, register
from patrolling_sim.common.protocol import MSG_DTA_IDLENESS
from patrolling_sim.algorithms.dta_common import IdlenessEstimate, decode_seconds, dta_params

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
        self._row_terms = {}

    def prepare(self, start_vertex):
        """The shortest-path table every decision reads, computed before GO (36 ms on
        broughton, i.e. a second of simulated time at x30 if left to the first decision)."""
        self.graph.dist

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.gi = IdlenessEstimate(self.graph.n, 100.0, now)
        self.gi.values[start_vertex] = 0.0
        if self.origin is None:
            self.origin = tuple(self.graph.pos[start_vertex])

    def on_arrival(self, vertex, now):
        super().on_arrival(vertex, now)
        self.gi.advance(now)[vertex] = 0.0

    def _terms(self, u):
        """(theta_navigation * pathcost(u, .), theta_distance_from_origin * |origin - .|,
        the vertices not to choose from u: u itself and the unreachable ones, whether any
        other is left), kept per u: they do not change during a run."""
        t = self._row_terms.get(u)
        if t is None:
            p = self.p
            if self._origin_dist is None:
                self._origin_dist = np.hypot(self.graph.pos[:, 0] - self.origin[0],
                                             self.graph.pos[:, 1] - self.origin[1])
            excluded = ~np.isfinite(self.graph.dist[u])
            excluded[u] = True
            t = self._row_terms[u] = (p["theta_navigation"] * self.graph.dist[u],
                                      p["theta_distance_from_origin"] * self._origin_dist,
                                      excluded, not excluded.all())
        return t

    def utility(self, u, g):
        """Utility of every vertex as a goal from u (numpy array)."""
        nav, origin = self._terms(u)[:2]
        return self.p["theta_idleness"] * g + nav + origin

    def choose_next(self, now):
        """Zero the current vertex's estimate, then the first maximum of the utility over
        the other reachable vertices (the original's compute_next_vertex)."""
        u = self.current
        g = self.gi.advance(now)
        g[u] = 0.0
        excluded, any_left = self._terms(u)[2:]
        if not any_left:
            return u
        score = self.utility(u, g)
        score[excluded] = -np.inf
        return int(np.argmax(score))        # first maximum, as the original

    def send_results(self, now):
        self.send(MSG_DTA_IDLENESS, *self.gi.encode(now, zero=self.next), self.next)

    def on_message(self, data, now):
        dec = decode_seconds(data, self.graph)
        if dec is None or self.gi is None:
            return
        values, their_next = dec
        self.gi.merge_seconds(values, now)
        if self.next is not None and their_next == self.next:
            self.current = self.next        # as if reached (not reported)
            self.next = self.choose_next(now)
            self.driver.redirect(self.next)
