"""MSP, Multilevel Subgraph Patrolling (Portugal & Rocha, ACM SAC 2010).

The graph is split into N balanced connected regions, one per robot, and each robot loops
over a closed route of its own region. The original read offline route files
``MSP/<map>/<map>_<N>_<i>``; those are used when they are valid closed walks on the current
graph (grid's are), otherwise (stale files, or no file for this team size) the partition and
routes are computed here: :func:`patrolling_sim.planning.routes.balanced_partition` plus
:func:`patrolling_sim.planning.routes.closed_route` per region. All robots compute the same
partition; regions are matched to robots by start position when the team's start vertices
are known (``ctx.params['start_vertices']``), else region i goes to robot i. ``MSP_BAL``
(:mod:`~patrolling_sim.algorithms.msp_bal`) always uses the computed partition.
"""
import logging
import os

import numpy as np
from scipy.optimize import linear_sum_assignment

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.planning.msp_routes import load_route
from patrolling_sim.planning.routes import balanced_partition, closed_route
from patrolling_sim.algorithms.base import PatrolStrategy, register
from patrolling_sim.algorithms.cgg import RouteFollower, rotate_to

log = logging.getLogger(__name__)


def assign_regions(pgraph, regions, start_vertices):
    """Region index per robot: a one-to-one matching of ``regions`` (lists of vertices) to
    robots (their ``start_vertices``) that first minimises the longest graph distance from
    a robot's start vertex to its region (a bottleneck assignment: no robot is left with a
    far region while a nearer matching exists), then the sum of those distances
    (deterministic). Needs as many regions as robots.

    Uses :func:`scipy.optimize.linear_sum_assignment` (the Hungarian method) for both
    steps: the bottleneck is the smallest distance threshold under which a perfect matching
    exists, found by bisection over the distinct distances.
    """
    D = pgraph.dist
    cost = np.array([[min(D[s, v] for v in reg) for reg in regions] for s in start_vertices],
                    dtype=float)
    big = 1.0 + cost.sum() * 2 * len(regions)

    def matching(limit):
        c = np.where(cost <= limit, cost, big)
        rows, cols = linear_sum_assignment(c)
        return cols[np.argsort(rows)], bool((c[rows, cols] < big).all())

    levels = np.unique(cost)
    lo, hi = 0, len(levels) - 1              # a perfect matching exists at levels[hi]
    while lo < hi:
        mid = (lo + hi) // 2
        if matching(levels[mid])[1]:
            hi = mid
        else:
            lo = mid + 1
    return [int(i) for i in matching(levels[lo])[0]]


def msp_route(pgraph, map_name, team_size, robot_id, start_vertices=None, route_file=None):
    """(route, source) for one robot: a valid shipped file, else a computed region route."""
    path = route_file or paths.msp_route_file(map_name, team_size, robot_id)
    if os.path.isfile(path):
        try:
            return load_route(path, pgraph), path
        except PatrolInputError as e:
            if route_file:
                raise
            log.info("MSP: %s; computing the partition instead", e)
    return msp_balanced_route(pgraph, team_size, robot_id, start_vertices)


def msp_balanced_route(pgraph, team_size, robot_id, start_vertices=None):
    """(route, "computed"): this project's balanced partition, region matched to the robot
    by start position when the team's start vertices are known (else region ``robot_id``)."""
    regions = balanced_partition(pgraph, team_size)
    if start_vertices and len(start_vertices) == team_size:
        idx = assign_regions(pgraph, regions, start_vertices)[robot_id]
    else:
        idx = robot_id
    return closed_route(pgraph, regions[idx]), "computed"


def start_in_region(s, start_vertex):
    """Rotate a route follower's closed route ``s.route`` to begin at the region's vertex
    closest to ``start_vertex`` when the robot stands outside its region."""
    if start_vertex not in s.route:
        D = s.graph.dist
        cyc = s.route[:-1]
        k = min(range(len(cyc)), key=lambda j: (D[start_vertex, cyc[j]], j))
        cyc = cyc[k:] + cyc[:k]
        s.route = cyc + cyc[:1]
        s.k = 0                         # current is off the route: the first choice is cyc[0]


@register
class MultilevelSubgraphPatrolling(RouteFollower):
    """The original's MSP: robot i follows ``MSP/<map>/<map>_<N>_<i>`` (or the
    ``msp_route`` file given): first goal the file's second entry, then the next ones,
    wrapping to the second entry after the last -- wherever the robot starts (it is not
    realigned to its start vertex). Where no valid file exists (the original cannot run
    there) the route of ``MSP_BAL`` is used instead, from the robot's own vertex (logged)."""
    name = "MSP"

    def build_route(self, start_vertex):
        p = self.ctx.params
        route, self.route_source = msp_route(
            self.graph, self.ctx.map_name, self.ctx.team_size, self.id,
            start_vertices=p.get("start_vertices"), route_file=p.get("msp_route"))
        return route

    def start(self, start_vertex, now):
        PatrolStrategy.start(self, start_vertex, now)
        route = self.prepared_route(start_vertex)
        if self.route_source == "computed":
            log.info("MSP: no valid route file for %s with %d robots; robot %d follows the "
                     "computed balanced partition (as MSP_BAL)", self.ctx.map_name,
                     self.ctx.team_size, self.id)
            self.route = rotate_to(route, start_vertex)
            self.k = 0
            start_in_region(self, start_vertex)
        else:
            self.route = route
            self.i = 0                  # index of the entry last sent as a goal

    def choose_next(self, now):
        if self.route_source == "computed":
            return super().choose_next(now)
        self.i += 1
        if self.i >= len(self.route):
            self.i = 1
        return self.route[self.i]

    def on_goal_failed(self, vertex, now):
        if self.route_source == "computed":
            return super().on_goal_failed(vertex, now)
        return PatrolStrategy.on_goal_failed(self, vertex, now)
