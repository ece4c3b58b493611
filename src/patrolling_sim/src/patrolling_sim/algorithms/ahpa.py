"""AHPA, Adaptive Heuristic-based Patrolling Algorithm (Goeckner, Li, Wei, Zhu,
"Attrition-Aware Adaptation for Multi-Agent Patrolling", arXiv 2304.01386).

The graph is split into graph-Voronoi cells, one per live robot: every vertex belongs to the
robot whose *seed* vertex reaches it at the smallest path cost (``dist[seed, v]``), ties to
the lower robot id. Each robot loops over a short closed tour of its own cell
(:func:`patrolling_sim.planning.routes.closed_route`: a travelling-salesman tour inside the
cell, expanded into graph edges, so every vertex on the way is a goal of its own). When a
teammate is lost -- silent for ``teammate_timeout`` s (``on_teammate_silent``) -- its seed is
dropped and the cells are recomputed from the survivors; when it is heard again it rejoins
and the cells are recomputed again.

Seeds (``ahpa_seeds``): ``start`` (default), the robots' start vertices, as the authors'
implementation does (it drops the lost robot's origin and keeps the others); ``current``,
each survivor re-seeds on its current vertex at every change of the team (a loss, a rejoin,
its own repair), and until a teammate announces its new seed its last reported vertex
stands in for it.

Messages: after every visit a robot broadcasts ``[id, 56, vertex, seed]``; it is also the
sign of life the silence check counts. No robot knows its teammates' seeds before GO, so the
first decision announces the robot's own seed and waits (``next_vertex`` returns None) until
every teammate's seed is known or ``ahpa_start_wait`` s have passed; a seed learnt later
shrinks the cell at the next decision. The life cycle gives strategies only algorithm
messages (types >= 30): the failure report ``[i, 13, 0]`` never reaches them, so a loss is
learnt from silence alone.
"""
from typing import Dict, List

import numpy as np

from patrolling_sim.algorithms.base import PatrolStrategy, register
from patrolling_sim.common.protocol import MSG_AHPA_POSITION
from patrolling_sim.planning.routes import closed_route, tsp_tour

#: the ``ahpa_seeds`` values
SEED_MODES = ("start", "current")
#: default s the first decision waits for the teammates' seeds
START_WAIT = 3.0


def voronoi_cells(pgraph, seeds: Dict[int, int]) -> Dict[int, List[int]]:
    """Graph-Voronoi cells: ``seeds`` maps robot id -> seed vertex; every vertex goes to the
    robot whose seed reaches it at the smallest path cost, ties to the lower robot id.
    Returns robot id -> sorted vertex list. A vertex no seed reaches belongs to nobody; a
    robot whose seed a lower id shares gets an empty cell."""
    robots = sorted(seeds)
    cells = {r: [] for r in robots}
    if not robots:
        return cells
    rows = np.asarray(pgraph.dist)[[seeds[r] for r in robots]]
    owner = np.argmin(rows, axis=0)              # first minimum: the lowest robot id
    reached = np.isfinite(rows.min(axis=0))
    for v in np.flatnonzero(reached):
        cells[robots[int(owner[v])]].append(int(v))
    return cells


def cell_walk(pgraph, cell: List[int], seed: int = 1000) -> List[int]:
    """A closed walk (first == last) over ``cell``: the tour inside the cell where the cell
    is connected on its own, else a tour over the whole graph's path costs expanded with the
    graph's shortest paths."""
    try:
        return closed_route(pgraph, cell, seed=seed)
    except ValueError:
        tour = tsp_tour(pgraph.dist, sorted(cell), seed=seed)
        walk = [tour[0]]
        for a, b in zip(tour, tour[1:] + tour[:1]):
            walk.extend(pgraph.path(a, b)[1:] if a != b else [b])
        return walk


@register
class AdaptiveHeuristicPatrolling(PatrolStrategy):
    name = "AHPA"

    def __init__(self, ctx):
        super().__init__(ctx)
        p = ctx.params
        self.seed_mode = str(p.get("ahpa_seeds", "start"))
        if self.seed_mode not in SEED_MODES:
            raise ValueError(f"AHPA: ahpa_seeds must be one of {', '.join(SEED_MODES)}, "
                             f"got '{self.seed_mode}'")
        self.start_wait = float(p.get("ahpa_start_wait", START_WAIT))
        self.route_seed = int(p.get("route_seed", 1000))
        self.algorithm_params = f"{self.seed_mode},{self.start_wait:g}"
        self.seeds: Dict[int, int] = {}     # robot -> seed vertex (own included)
        self.where: Dict[int, int] = {}     # robot -> last vertex it reported
        self.alive = set()                  # robots whose cells count (own included)
        self.cell: List[int] = []
        self.cyc: List[int] = []            # own tour, without the repeated endpoint
        self.k = 0                          # index in cyc of the vertex last reached
        self.approach: List[int] = []       # path steps into the cell
        self.stale = True                   # cells to recompute at the next decision
        self.ready = False
        self.announced = False
        self.t_start = 0.0
        self.replans = 0

    def prepare(self, start_vertex):
        """The path-cost table the cells are grown on, before GO."""
        self.graph.dist

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.seeds = {self.id: start_vertex}
        self.where = {self.id: start_vertex}
        self.alive = {self.id}
        self.t_start = now
        self.ready = self.ctx.team_size <= 1
        self.stale = True

    # -- deciding ---------------------------------------------------------------------
    def next_vertex(self, now):
        if not self.ready:
            if not self.announced:
                self.announced = True
                self._announce()
            waiting = (len(self.seeds) < self.ctx.team_size
                       and now - self.t_start < self.start_wait
                       and getattr(self.driver, "accepts_pending_decision", True))
            if waiting:
                return None
            self.ready = True
        return super().next_vertex(now)

    def choose_next(self, now):
        if self.stale:
            self.replan()
        if self.approach:
            return self.approach.pop(0)
        if len(self.cyc) > 1 and self.current == self.cyc[self.k]:
            self.k = (self.k + 1) % len(self.cyc)
        return self.cyc[self.k]

    def replan(self):
        """Recompute the cells from the live robots' seeds and head for the own one: from the
        current vertex if it is on the new tour, else along the shortest path to the tour's
        nearest vertex."""
        self.stale = False
        self.replans += 1
        seeds = {r: self.seeds[r] for r in self.alive if r in self.seeds}
        cells = voronoi_cells(self.graph, seeds)
        cell = cells[self.id]
        if not cell:           # a lower id shares the seed vertex: share its cell
            cell = cells[min(r for r in seeds if seeds[r] == seeds[self.id])]
        self.cell = cell
        cyc = cell_walk(self.graph, cell, self.route_seed)[:-1]
        u = self.current
        if u in cyc:
            entry = cyc.index(u)
            self.approach = []
        else:
            d = self.graph.dist[u]
            entry = min(range(len(cyc)), key=lambda j: (d[cyc[j]], j))
            self.approach = self.graph.path(u, cyc[entry])[1:]
        self.cyc = cyc[entry:] + cyc[:entry]
        self.k = 0

    def on_goal_failed(self, vertex, now):
        """Skip the unreachable vertex: on to the tour's entry, or the vertex after it."""
        if self.approach:
            self.approach = []
        elif len(self.cyc) > 1:
            self.k = (self.k + 1) % len(self.cyc)
        self.next = self.cyc[self.k]
        return self.next

    # -- the team ---------------------------------------------------------------------
    def _announce(self):
        self.send(MSG_AHPA_POSITION, self.current, self.seeds[self.id])

    def send_results(self, now):
        self._announce()

    def _team_changed(self):
        """A loss, a rejoin or an own repair: cells to recompute; with ``current`` seeds the
        robot re-seeds on its current vertex and takes its teammates' last reported vertices
        until they announce their own."""
        self.stale = True
        if self.seed_mode == "current":
            for r in self.alive:
                if r in self.where:
                    self.seeds[r] = self.where[r]
            self.seeds[self.id] = self.current

    def on_message(self, data, now):
        if len(data) < 4 or data[1] != MSG_AHPA_POSITION:
            return
        r, v, s = int(data[0]), int(data[2]), int(data[3])
        if not (0 <= v < self.graph.n and 0 <= s < self.graph.n):
            return
        self.where[r] = v
        if r not in self.alive:
            self.alive.add(r)
            if self.ready:
                self._team_changed()
        if self.seeds.get(r) != s:
            self.seeds[r] = s
            self.stale = True

    def on_teammate_silent(self, robot_id, now):
        if robot_id in self.alive:
            self.alive.discard(robot_id)
            self._team_changed()

    def on_repair(self, now):
        self._team_changed()
