"""MSP's computed partition: regions are matched to robots so that no robot is sent farther
than it must be (the bottleneck of the matching is the smallest possible), then the total
distance is the smallest among such matchings."""
import itertools

import pytest

from patrolling_sim.algorithms.msp import assign_regions
from patrolling_sim.common import paths
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.starts import start_vertices_of
from patrolling_sim.model.graph import PatrolGraph, load_graph
from patrolling_sim.planning.routes import balanced_partition


def _trips(g, regions, starts, assignment):
    return [min(g.dist[s, v] for v in regions[assignment[r]]) for r, s in enumerate(starts)]


@pytest.mark.parametrize("map_name,robots", [("DIAG_labs", 8), ("ctcv", 8), ("grid", 6),
                                             ("DIAG_floor1", 4), ("broughton", 6)])
def test_matching_is_bottleneck_optimal(map_name, robots):
    g = PatrolGraph(load_graph(paths.map_files(map_name)[1], warn=False))
    starts = start_vertices_of(GraphSimConfig(map=map_name, robots=robots, alg="MSP_BAL"), g)
    regions = balanced_partition(g, robots)
    got = assign_regions(g, regions, starts)
    assert sorted(got) == list(range(robots))            # one region per robot
    trips = _trips(g, regions, starts, got)
    every = (_trips(g, regions, starts, p) for p in itertools.permutations(range(robots)))
    best = min((max(t), sum(t)) for t in every)
    assert (max(trips), sum(trips)) == pytest.approx(best)
