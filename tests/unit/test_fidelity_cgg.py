"""CGG's route on every shipped map: the original's construction (docs/fidelity.md, CGG).

Grid has a Hamiltonian path (checked against the original's runs in test_fidelity.py); on
every other map the original builds its longest cycle or longest path with detours
(``patrolling_sim.planning.cyclic_route``). The pinned figures below were computed by that code; the
properties checked next to them (every vertex and every edge covered, consecutive entries
adjacent, a path walked back from a degree-1 vertex, a cycle closed on itself) hold for the
original's construction and would catch a wrong port. On example the route is also checked
entry by entry against the one the original's own Cyclic agents printed ("Final Path" in
their logs, robots at vertices 17 and 0, abstract world).
"""
import logging

import pytest

from patrolling_sim.common import paths
from patrolling_sim.algorithms import StrategyContext, create
from patrolling_sim.algorithms.cgg import original_cyclic_route
from patrolling_sim.planning.cyclic_route import (RouteConstructionError, _Web, cyclic_route,
                                                  longest_path, outbound_walk)
from patrolling_sim.model.graph import PatrolGraph, parse_graph
from patrolling_sim.planning.routes import route_cost

#: map -> (main route kind, entries, cost in the graph's units, first entries)
PINNED = {
    "cumberland": ("path", 145, 10760, [0, 2, 1, 2, 4, 3, 4, 6, 7, 5]),
    "DIAG_labs": ("path", 79, 3554, [1, 5, 11, 5, 6, 2, 6, 7, 12, 7]),
    "broughton": ("path", 673, 29510, [7, 8, 2, 0, 1, 3, 1, 0, 2, 3]),
    "1r5": ("path", 37, 2512, [3, 1, 0, 1, 5, 10, 8, 10, 11, 10]),
    "ctcv": ("path", 43, 2664, [0, 1, 2, 1, 4, 3, 4, 5, 6, 7]),
    "example": ("cycle", 53, 2572, [10, 9, 7, 9, 15, 9, 10, 11, 5, 6]),
    "DIAG_floor1": ("path", 191, 12628, [4, 8, 6, 0, 6, 5, 1, 5, 7, 2]),
    "move_base_arena": ("cycle", 29, 1831, [6, 5, 6, 11, 13, 11, 3, 12, 3, 13]),
    "grid": ("hamiltonian", 49, 3648, [0, 1, 6, 5, 10, 11, 16, 15, 20, 21]),
}


def load(mapname):
    return PatrolGraph.load(paths.map_files(mapname)[1])


def test_every_shipped_map_is_pinned():
    assert sorted(PINNED) == paths.available_maps()


#: the original's Cyclic agents' "Final Path" on example (the route rotated to the first
#: occurrence of the robot's start vertex), copied from their logs
ORIGINAL_EXAMPLE = {
    17: [17, 22, 17, 18, 17, 11, 8, 12, 13, 3, 13, 18, 26, 19, 26, 28, 27, 28, 22, 21, 20, 21,
         24, 23, 24, 25, 24, 27, 20, 15, 16, 14, 10, 9, 7, 9, 15, 9, 10, 11, 5, 6, 5, 2, 5, 1,
         0, 1, 4, 1, 5, 11, 17],
    0: [0, 1, 4, 1, 5, 11, 17, 22, 17, 18, 17, 11, 8, 12, 13, 3, 13, 18, 26, 19, 26, 28, 27,
        28, 22, 21, 20, 21, 24, 23, 24, 25, 24, 27, 20, 15, 16, 14, 10, 9, 7, 9, 15, 9, 10, 11,
        5, 6, 5, 2, 5, 1, 0],
}


def test_example_route_is_the_one_the_original_agents_print():
    """example lists neighbours twice with another in between (vertices 8, 12, 16): the
    construction walks the lists in the file's order, as the original does."""
    from patrolling_sim.algorithms.cgg import rotate_to
    route, _ = original_cyclic_route(load("example"))
    for start, printed in ORIGINAL_EXAMPLE.items():
        assert rotate_to(route, start) == printed


@pytest.mark.parametrize("mapname", sorted(PINNED))
def test_route_as_the_original_builds_it(mapname):
    g = load(mapname)
    route, source = original_cyclic_route(g)
    kind, entries, cost, first = PINNED[mapname]
    assert (source, len(route), round(route_cost(g, route)), route[:len(first)]) == \
        (kind, entries, cost, first)
    assert set(route) == set(range(g.n))                        # every vertex
    assert all(g.arc_cost(a, b) is not None for a, b in zip(route, route[1:]))
    assert route[0] == route[-1]
    if source == "path":                                        # walked back from a leaf
        assert g.degree(route[0]) == 1
        half = len(route) // 2
        assert route[:half + 1] == route[half:][::-1]
    if source in ("path", "cycle"):                             # every edge walked
        walked = {frozenset(e) for e in zip(route, route[1:])}
        assert walked == {frozenset((u, w)) for u in range(g.n) for w in g.neighbor_ids(u)}


def test_robots_start_where_they_stand_on_the_shared_route():
    """As the original: each robot rotates the shared route to the first occurrence of its
    start vertex and then follows it."""
    g = load("cumberland")
    route, _ = original_cyclic_route(g)

    class _Drv:
        pass
    s = create("CGG", StrategyContext(g, 0, 2, "cumberland", None, _Drv(), {}))
    s.start(5, 0.0)
    k = route.index(5)
    assert s.route[:-1] == route[k:-1] + route[:k]
    seq = [s.next_vertex(0.0)]
    for t in range(len(route) + 3):
        s.on_arrival(seq[-1], float(t + 1))
        seq.append(s.choose_next(float(t + 1)))
    cyc = route[k:-1] + route[:k]
    assert seq == (cyc + cyc)[1:len(seq) + 1]


def test_num_arcs_is_the_smallest_that_covers_every_edge():
    g = load("DIAG_floor1")
    route, info = cyclic_route(g)
    web = _Web(g)
    main, _ = longest_path(web)
    assert info["main"] == "path" and len(main) == info["main_entries"]
    assert outbound_walk(web, main, info["num_arcs"])[1]
    assert not outbound_walk(web, main, info["num_arcs"] - 1)[1]


def _star_of_triangles():
    """A central triangle with a triangle hung on each corner by one edge: no Hamiltonian
    path, no degree-1 vertex, no cycle of V/2 entries."""
    edges = []
    for t in range(4):
        a, b, c = 3 * t, 3 * t + 1, 3 * t + 2
        edges += [(a, b), (b, c), (a, c)]
    edges += [(0, 3), (1, 6), (2, 9)]
    nb = {v: [] for v in range(12)}
    for a, b in edges:
        nb[a].append(b)
        nb[b].append(a)
    lines = ["12", "100", "100", "0.1", "0", "0", ""]
    for v in range(12):
        lines += [str(v), str(10 + 5 * v), str(10 + 3 * (v % 4)), str(len(nb[v]))]
        for w in nb[v]:
            lines += [str(w), "N", "10"]
        lines.append("")
    return PatrolGraph(parse_graph("\n".join(lines)))


def test_failed_construction_falls_back_to_the_short_tour_with_a_warning(caplog):
    g = _star_of_triangles()
    with pytest.raises(RouteConstructionError):
        cyclic_route(g)
    with caplog.at_level(logging.WARNING, logger="patrolling_sim.algorithms.cgg"):
        route, source = original_cyclic_route(g)
    assert source == "tsp" and set(route) == set(range(12)) and route[0] == route[-1]
    assert len([r for r in caplog.records if "CGG_TSP" in r.getMessage()]) == 1
