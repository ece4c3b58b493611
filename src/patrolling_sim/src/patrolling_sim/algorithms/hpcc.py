"""HPCC, Heuristic Pathfinder Conscientious Cognitive (``Conscientious_Cognitive``;
Almeida et al. 2004).

Goal: the vertex v != current maximising ``(Dmax - d(v)) / Dmax + idl[v] / Imax`` where d is
the shortest-path cost from the current vertex and Dmax, Imax are maxima over the candidates.
The robot then follows a Dijkstra path whose directed arc costs mix idleness and length,
``(Imax - idl[j]) / Imax + (c(i,j) - cmin) / (cmax - cmin)`` (global edge min/max; a term is
0 when its denominator is 0), so it prefers to pass through idle vertices. Every vertex of
that path is a goal of its own (and is reported); the goal is recomputed at the path's end.
Idleness is local.
"""
import heapq

import numpy as np

from patrolling_sim.algorithms.base import PatrolStrategy, register


@register
class HeuristicPathfinderConscientiousCognitive(PatrolStrategy):
    name = "HPCC"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.route = []                 # remaining path vertices to the current goal
        costs = self.graph.edge_costs()
        self.cmin, self.cmax = min(costs), max(costs)

    def choose_next(self, now):
        if not self.route:
            self.route = self._plan()
        return self.route.pop(0)

    def on_goal_failed(self, vertex, now):
        self.route = []
        return super().on_goal_failed(vertex, now)

    def _plan(self):
        u, g = self.current, self.graph
        d = np.asarray(g.dist[u], dtype=float)
        mask = np.isfinite(d)
        mask[u] = False
        cands = np.flatnonzero(mask)
        if not len(cands):
            return [u]
        idl = np.asarray(self.idleness, dtype=float)
        dv, iv = d[cands], idl[cands]
        dmax, imax = float(dv.max()), float(iv.max())
        score = (dmax - dv) / dmax if dmax > 0 else np.zeros(len(cands))
        score = score + (iv / imax if imax > 0 else 0.0)
        ties = cands[score >= score.max() - 1e-9].tolist()     # as argmax_random
        goal = ties[0] if len(ties) == 1 else self.tie_rng.choice(ties)
        return self._path(u, goal, imax)[1:]

    def _arc(self, i, j, imax):
        c = self.graph.arc_cost(i, j)
        a = (imax - self.idleness[j]) / imax if imax > 0 else 0.0
        b = (c - self.cmin) / (self.cmax - self.cmin) if self.cmax > self.cmin else 0.0
        return a + b

    def _path(self, s, t, imax):
        """Dijkstra with the idleness-weighted arc costs (ties: lower vertex id)."""
        g = self.graph
        dist = {s: 0.0}
        pred = {}
        heap = [(0.0, s)]
        done = set()
        while heap:
            du, u = heapq.heappop(heap)
            if u in done:
                continue
            done.add(u)
            if u == t:
                break
            for w in g.neighbor_ids(u):
                nd = du + self._arc(u, w, imax)
                if nd < dist.get(w, float("inf")):
                    dist[w] = nd
                    pred[w] = u
                    heapq.heappush(heap, (nd, w))
        path = [t]
        while path[-1] != s:
            path.append(pred[path[-1]])
        return path[::-1]
