"""CGG, cyclic strategy (``Cyclic``; Portugal & Rocha, ACM SAC 2010).

All robots build the same closed route over the whole graph, rotate it to begin at the first
occurrence of their own start vertex and follow it forever (skipping the repeated endpoint).
The route is the original's: a Hamiltonian path found by its seeded randomised walk
(:func:`patrolling_sim.planning.routes.hamiltonian_route`), closed by walking it back -- on grid
``0 1 6 5 10 11 16 15 20 21 22 17 18 23 24 19 14 9 4 3 2 7 12 13 8`` and back, 48 edges;
a Hamiltonian circuit where the walk finds one. The construction is seeded, so it has no
random element: the same route on every run.

Where the walk finds neither (every shipped map but grid) the route is the original's
second construction (:func:`patrolling_sim.planning.cyclic_route.cyclic_route`): its longest
cycle or longest path between degree-1 vertices, with detours over the edges it misses
(``num_arcs`` bisected), a path walked back. Should that construction fail (no cycle of V/2
entries and no two degree-1 vertices, a search over its step bound, or a route missing a
vertex), this module uses the short closed tour of :mod:`~patrolling_sim.algorithms.cgg_tsp`
and logs a one-line warning (see docs/fidelity.md). ``CGG_TSP`` always uses that tour.
"""
import logging

from patrolling_sim.planning.cyclic_route import RouteConstructionError, cyclic_route
from patrolling_sim.planning.routes import closed_route, hamiltonian_route
from patrolling_sim.algorithms.base import PatrolStrategy, register

log = logging.getLogger(__name__)


def rotate_to(route, vertex):
    """``route`` (closed, first == last) rotated to start at ``vertex``'s first occurrence;
    the result is closed again. If ``vertex`` is not on it, start at its first vertex."""
    cyc = route[:-1]
    k = cyc.index(vertex) if vertex in cyc else 0
    cyc = cyc[k:] + cyc[:k]
    return cyc + cyc[:1]


class RouteFollower(PatrolStrategy):
    """Base for strategies that loop over a fixed closed route (CGG, MSP)."""

    route = None                        # closed walk, set by subclasses in start()
    _prepared = None                    # (start vertex, route built for it before GO)

    def prepare(self, start_vertex):
        """Build the route before GO (the original's agents build it in their init)."""
        self._prepared = (start_vertex, self.build_route(start_vertex))

    def prepared_route(self, start_vertex):
        """The route :meth:`prepare` built for ``start_vertex``, else built now."""
        if self._prepared is not None and self._prepared[0] == start_vertex:
            return self._prepared[1]
        return self.build_route(start_vertex)

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.route = rotate_to(self.prepared_route(start_vertex), start_vertex)
        self.k = 0                      # index in the route of the vertex last reached

    def build_route(self, start_vertex):
        raise NotImplementedError

    def choose_next(self, now):
        cyc = self.route[:-1]
        if len(cyc) == 1:
            return cyc[0]
        if self.current == cyc[self.k % len(cyc)]:
            self.k = (self.k + 1) % len(cyc)
        return cyc[self.k]

    def on_goal_failed(self, vertex, now):
        # skip the unreachable vertex: carry on with the one after it
        cyc = self.route[:-1]
        self.k = (self.k + 1) % len(cyc)
        self.next = cyc[self.k]
        return self.next


def original_cyclic_route(pgraph):
    """(route, source): the original's route -- its Hamiltonian route (source
    "hamiltonian"), else its longest cycle / longest path with detours ("cycle" / "path"),
    else, where that construction fails, the short closed tour ("tsp", logged)."""
    cache = pgraph.derived.setdefault("cgg_route", {})
    if "route" not in cache:
        route = hamiltonian_route(pgraph)
        if route is not None:
            cache["route"] = (route, "hamiltonian")
        else:
            try:
                route, info = cyclic_route(pgraph)
                if set(route) != set(range(pgraph.n)):
                    raise RouteConstructionError("CGG route: the route misses a vertex")
                cache["route"] = (route, info["main"])
            except RouteConstructionError as err:
                log.warning("%s on graph '%s'; CGG uses the short closed tour of CGG_TSP "
                            "instead", err, pgraph.name)
                cache["route"] = (closed_route(pgraph), "tsp")
    route, source = cache["route"]
    return list(route), source


@register
class Cyclic(RouteFollower):
    name = "CGG"

    def build_route(self, start_vertex):
        route, self.route_source = original_cyclic_route(self.graph)
        return route
