"""CGG, cyclic strategy (``Cyclic``; Portugal & Rocha, ACM SAC 2010).

All robots build the same closed route over the whole graph (deterministic:
:func:`patrolling_sim.routes.closed_route`), rotate it to begin at their own start vertex and
follow it forever. The route is a short closed walk — on grid 26 edges / 148.2 m, where the
original's randomised builder produced a 49-edge out-and-back walk of about 279 m.
"""
from ..routes import closed_route
from .base import PatrolStrategy, register


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

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.route = rotate_to(self.build_route(start_vertex), start_vertex)
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


@register
class Cyclic(RouteFollower):
    name = "CGG"

    def build_route(self, start_vertex):
        return closed_route(self.graph, seed=int(self.ctx.params.get("route_seed", 1000)))
