"""CGG_TSP: CGG's rule (every robot loops over one shared closed route, starting from its own
vertex) on a short closed tour instead of the original's route -- an improvement of this
project, not an algorithm of the original.

The tour (:func:`patrolling_sim.planning.routes.closed_route`) is a travelling-salesman tour over
shortest-path costs, expanded into graph edges: on grid 26 edges / 148.2 m against the
original CGG's 48-edge out-and-back walk of about 274 m, so each vertex is revisited about
twice as often. ``route_seed`` (default 1000) seeds its restarts.
"""
from patrolling_sim.planning.routes import closed_route
from patrolling_sim.algorithms.base import register
from patrolling_sim.algorithms.cgg import RouteFollower


@register
class CyclicTSP(RouteFollower):
    name = "CGG_TSP"

    def build_route(self, start_vertex):
        return closed_route(self.graph, seed=int(self.ctx.params.get("route_seed", 1000)))
