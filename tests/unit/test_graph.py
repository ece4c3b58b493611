"""Patrol graph loader: shipped graphs, coordinates, round trip, malformed input."""

import pytest

from patrolling_sim.common import paths
from patrolling_sim.common.errors import GraphFormatError
from patrolling_sim.model.graph import (PatrolGraph, format_graph, graph_warnings, graphs_equal,
                                        load_graph, parse_graph, printed_edge_count,
                                        undirected_edge_count)
from spqrel_nav_lite.mapio import load_map

# the shipped maps (maps/README.md): V, E (distinct pairs), E* (as the original prints)
SHIPPED = {
    "grid": (25, 40, 40), "example": (29, 34, 36), "cumberland": (40, 44, 44),
    "1r5": (12, 11, 11), "broughton": (163, 186, 186), "DIAG_labs": (27, 26, 26),
    "DIAG_floor1": (60, 63, 63), "ctcv": (18, 17, 17), "move_base_arena": (14, 22, 22),
}


def test_all_shipped_maps_present():
    assert sorted(paths.available_maps()) == sorted(SHIPPED)


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_graph_counts(name):
    yaml_path, graph_path = paths.map_files(name)
    G = load_graph(graph_path)
    V, E, Estar = SHIPPED[name]
    assert G.number_of_nodes() == V
    assert undirected_edge_count(G) == E
    assert printed_edge_count(G) == Estar
    occ = load_map(yaml_path)
    # header matches the image, and after the data fixes no graph has warnings
    assert (G.graph["width_px"], G.graph["height_px"]) == (occ.width, occ.height)
    assert graph_warnings(G, occ) == []


def test_grid_coordinates():
    G = load_graph(paths.map_files("grid")[1])
    assert G.nodes[0]["pos"] == pytest.approx((1.425, 24.375))
    assert G.nodes[1]["pos"] == pytest.approx((1.425, 18.675))
    assert G.nodes[0]["x_px"] == 19 and G.nodes[0]["y_px"] == 325
    e = G.get_edge_data(0, 1)[0]
    assert e["cost_px"] == 76 and e["cost_m"] == pytest.approx(5.7) and e["direction"] == "S"


def test_ctcv_offsets_and_multi_edges_kept():
    G = load_graph(paths.map_files("ctcv")[1])
    assert G.graph["offset_x"] == pytest.approx(-29.675)
    ex = load_graph(paths.map_files("example")[1])
    assert len(ex.get_edge_data(14, 16)) == 2      # listed twice, both kept


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_round_trip(name, tmp_path):
    G = load_graph(paths.map_files(name)[1])
    text = format_graph(G)
    G2 = parse_graph(text, "x.graph")
    assert graphs_equal(G, G2)
    assert format_graph(G2) == text
    out = tmp_path / "rt.graph"
    out.write_text(text)
    assert graphs_equal(G, load_graph(str(out)))


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_file_order_of_neighbours_kept(name):
    """The neighbour lists come back in the file's order, also where a vertex lists a
    neighbour twice with another in between (example: 8, 12, 16), which networkx alone
    groups: the original's agents walk the lists in file order (its CGG route depends on
    it)."""
    path = paths.map_files(name)[1]
    with open(path) as f:
        tokens = f.read().split()
    assert format_graph(load_graph(path)).split()[6:] == tokens[6:]   # past the header
    g = PatrolGraph.load(path)
    i = 6
    for v in range(g.n):
        k = int(tokens[i + 3])
        listed = [int(tokens[i + 4 + 3 * j]) for j in range(k)]
        assert [w for w, _ in g.neighbors[v]] == listed, f"{name} vertex {v}"
        i += 4 + 3 * k


def test_interleaved_multi_edge_order():
    text = "3 10 10 1 0 0\n0 1 1 3 1 E 2 2 N 3 1 E 4\n1 3 1 1 0 W 2\n2 1 3 1 0 S 3\n"
    g = PatrolGraph(parse_graph(text, "m.graph"))
    assert g.neighbors[0] == [(1, 2), (2, 3), (1, 4)]
    assert format_graph(g.G).split()[6:19] == "0 1 1 3 1 E 2 2 N 3 1 E 4".split()


def test_patrol_graph_tables():
    pg = PatrolGraph(load_graph(paths.map_files("grid")[1]))
    assert pg.n == 25
    assert pg.dist[0, 24] == 8 * 76          # opposite corners of the 5x5 lattice
    p = pg.path(0, 24)
    assert p[0] == 0 and p[-1] == 24 and len(p) == 9
    assert all(pg.arc_cost(a, b) == 76 for a, b in zip(p, p[1:]))
    assert pg.hops[0, 24] == 8
    assert pg.nearest_vertex(1.5, 24.0) == 0


GOOD = "3 10 10 0.5 0 0\n0 1 1 1 1 E 2\n1 3 1 2 0 W 2 2 N 2\n2 3 3 1 1 S 2\n"


def _err(text, tmp_path):
    p = tmp_path / "bad.graph"
    p.write_text(text)
    with pytest.raises(GraphFormatError) as ei:
        load_graph(str(p))
    msg = str(ei.value)
    assert "\n" not in msg and str(p) in msg
    return msg


def test_good_small_graph_parses():
    G = parse_graph(GOOD, "good.graph")
    assert G.number_of_nodes() == 3 and G.nodes[2]["pos"] == (1.5, 1.5)


@pytest.mark.parametrize("text,needle", [
    ("", "truncated"),                                                   # empty
    ("3 10 10 0.5 0 0\n0 1 1 1 1 E 2\n1 3 1 2 0 W 2", "truncated"),      # cut mid-record
    ("3 10 10 abc 0 0\n", "resolution (m/px) must be a number, got 'abc'"),
    ("3 10 10 0.5 0 0\n0 1 1 1 1 E x2\n", "must be an integer, got 'x2'"),
    ("x 10 10 0.5 0 0\n", "vertex count must be an integer"),
    ("0 10 10 0.5 0 0\n", "vertex count must be >= 1"),
    ("3 10 10 0.5 0 0\n0 1 1 1 7 E 2\n", "neighbour id 7 of vertex 0 is out of range"),
    ("3 10 10 0.5 0 0\n0 1 1 1 1 Q 2\n", "direction of edge 0->1"),
    ("3 10 10 0.5 0 0\n0 1 1 1 1 E -2\n", "must be >= 0"),
    ("3 10 10 0.5 0 0\n1 1 1 0\n", "vertex record 0 has id 1"),
    ("2 10 10 0.5 0 0\n0 1 1 1 1 E 2\n1 3 1 1 0 W 2\n2 3 3 0\n", "unexpected data '2'"),
    ("3 10 10 -0.5 0 0\n", "positive"),
    ("3 10 10 0.5 0 0\n0 1 1 1 0 E 2\n", "lists itself"),
])
def test_malformed_graphs(text, needle, tmp_path):
    assert needle in _err(text, tmp_path)


def test_error_names_line(tmp_path):
    msg = _err("3 10 10 0.5 0 0\n0 1 1 1 1 E 2\n1 3 1 2 0 W 2 9 N 2\n", tmp_path)
    assert "bad.graph:3:" in msg


def test_missing_graph_file(tmp_path):
    with pytest.raises(GraphFormatError, match="not found"):
        load_graph(str(tmp_path / "nope.graph"))


def test_warnings_asymmetric_disconnected_occupied():
    text = "4 10 10 1 0 0\n0 1 1 1 1 E 2\n1 3 1 1 0 W 5\n2 5 5 1 3 E 1\n3 6 5 1 2 W 1\n"
    G = parse_graph(text, "w.graph")
    w = graph_warnings(G)
    assert any("asymmetric edge cost 0->1" in x for x in w)
    assert any("disconnected (2 components)" in x for x in w)
    occ = load_map(paths.map_files("grid")[0])
    G2 = parse_graph("1 344 344 0.075 0 0\n0 0 0 0\n", "o.graph")   # corner = wall
    assert any("occupied" in x for x in graph_warnings(G2, occ))


def _settle_order_tables(g):
    """Oracle for graph_tables' tie rule, written as a plain Dijkstra ordered by (cost,
    vertex id) with strict improvement: (dist, next hop) of every pair."""
    import heapq
    import numpy as np
    n = g.n
    dist = np.full((n, n), np.inf)
    nxt = np.full((n, n), -1, dtype=int)
    for s in range(n):
        d, pred, done, heap = dist[s], [-1] * n, [False] * n, [(0.0, s)]
        d[s] = 0.0
        while heap:
            du, u = heapq.heappop(heap)
            if done[u]:
                continue
            done[u] = True
            for w, c in g.neighbors[u]:
                if du + c < d[w]:
                    d[w], pred[w] = du + c, u
                    heapq.heappush(heap, (du + c, w))
        for t in range(n):
            u = t
            while t != s and pred[t] != -1 and pred[u] != s:
                u = pred[u]
            nxt[s, t] = u if t != s and pred[t] != -1 else -1
    return dist, nxt


def _random_graph(rng, n, costs):
    import networkx as nx
    G = nx.MultiDiGraph(resolution=0.1)
    for v in range(n):
        G.add_node(v, pos=(0.0, 0.0), x_px=0, y_px=0)
    for _ in range(rng.randint(0, 3 * n)):
        u, w = rng.randrange(n), rng.randrange(n)
        if u != w:
            c = rng.choice(costs)
            G.add_edge(u, w, cost_px=c)
            if rng.random() < 0.8:
                G.add_edge(w, u, cost_px=c)
    return G


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_path_tables_follow_the_tie_rule_on_shipped_maps(name):
    import networkx as nx
    import numpy as np
    g = PatrolGraph(load_graph(paths.map_files(name)[1], warn=False))
    dist, nxt = _settle_order_tables(g)
    assert np.array_equal(g.dist, dist)
    assert np.array_equal(g._next, nxt)
    hops = dict(nx.all_pairs_shortest_path_length(nx.DiGraph(g.G)))
    assert all(g.hops[s, t] == hops[s].get(t, np.inf) for s in range(g.n) for t in range(g.n))
    assert g.neighbor_ids(0) is g.neighbor_ids(0)          # precomputed, not rebuilt


def test_path_tables_follow_the_tie_rule_with_many_ties():
    import random
    import numpy as np
    rng = random.Random(3)
    for trial in range(200):
        g = PatrolGraph(_random_graph(rng, rng.randint(1, 25), [1, 2] if trial % 2 else
                                      [1, 2, 3, 5, 10]))
        dist, nxt = _settle_order_tables(g)
        assert np.array_equal(g.dist, dist) and np.array_equal(g._next, nxt), trial


def test_zero_cost_edges_give_valid_shortest_paths():
    import random
    rng = random.Random(5)
    for _ in range(50):
        g = PatrolGraph(_random_graph(rng, rng.randint(2, 12), [0, 0, 1, 2]))
        for s in range(g.n):
            for t in range(g.n):
                p = g.path(s, t)
                if g.dist[s, t] == float("inf"):
                    assert p is None
                else:
                    assert p[0] == s and p[-1] == t
                    assert sum(g.arc_cost(a, b) for a, b in zip(p, p[1:])) == g.dist[s, t]
