"""MSP_BAL: balanced-partition patrolling, this project's variant of MSP (not an algorithm of
the original; see docs/fidelity.md)."""
from patrolling_sim.algorithms.base import register
from patrolling_sim.algorithms.cgg import RouteFollower
from patrolling_sim.algorithms.msp import msp_balanced_route, start_in_region


@register
class BalancedSubgraphPatrolling(RouteFollower):
    """MSP_BAL (this project's, not the original's): MSP's idea on partitions computed here
    for any map and team size -- :func:`patrolling_sim.planning.routes.balanced_partition` into N
    connected regions of near-equal size, a short closed route per region
    (:func:`patrolling_sim.planning.routes.closed_route`), regions matched to robots by
    distance from their start vertices, each robot starting its route at its own vertex (or
    the region's nearest vertex). The shipped route files are not used."""
    name = "MSP_BAL"
    #: each robot follows its own region's route (not one route shared by the team)
    shared_route = False

    def build_route(self, start_vertex):
        route, self.route_source = msp_balanced_route(
            self.graph, self.ctx.team_size, self.id, self.ctx.params.get("start_vertices"))
        return route

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        start_in_region(self, start_vertex)
