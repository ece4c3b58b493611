"""Metrics beyond the original's (patrolling_sim.monitor.metrics) on hand-computed visit logs, and
the theoretical references (patrolling_sim.planning.references) on graphs whose answer is known."""
import itertools
import math

import networkx as nx
import numpy as np
import pytest

from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.monitor.metrics import compute_metrics, read_visits
from patrolling_sim.planning.references import _held_karp, best_tour_length, references


def test_hand_computed_two_vertices():
    # V = 2, T = 10 s; vertex 0 visited at 2 and 6, vertex 1 at 4.
    # vertex 0 idleness gaps 2, 4, 4 -> area 2 + 8 + 8 = 18; vertex 1 gaps 4, 6 -> 8 + 18 = 26
    m = compute_metrics([(2.0, 0, 0), (4.0, 1, 1), (6.0, 0, 0)], n_vertices=2, duration=10.0)
    assert m.time_avg_idleness == pytest.approx(44.0 / 20.0)
    assert m.worst_idleness == pytest.approx(6.0)            # vertex 1 from 4 s to the end
    assert m.sample_avg_idleness == pytest.approx(4.0)       # the original's: one sample (6 - 2)
    assert m.sample_max_idleness == pytest.approx(4.0)
    # max over vertices: t on [0,4] (8), t-2 on [4,6] (6), t-4 on [6,10] (16) -> 30 / 10
    assert m.time_avg_max_idleness == pytest.approx(3.0)
    assert m.per_vertex_visits == [2, 1]
    assert m.visit_frequency_mean == pytest.approx(540.0)    # (720 + 360) / 2 per hour
    assert m.visit_frequency_sd == pytest.approx(180.0)
    assert m.never_visited == 0
    assert m.n_visits == 3
    assert m.sample_coverage == pytest.approx(4.0 / 20.0)   # one 4 s sample in V x T = 20 s


def test_sample_average_is_spans_over_samples_and_coverage_counts_closed_gaps():
    # A vertex reached late, one left early and one never visited: their open gaps leave the
    # samples, so the sample average stays low while most of the run is outside it.
    visits = [(0.0, 0, 0), (10.0, 0, 0), (20.0, 0, 0),    # vertex 0: two 10 s samples
              (80.0, 1, 1), (90.0, 1, 1),                  # vertex 1: first visit at 80 s
              (0.0, 2, 2), (5.0, 2, 2)]                    # vertex 2: last visit at 5 s
    m = compute_metrics(visits, n_vertices=4, duration=100.0)
    # sum over vertices of (last - first) = 20 + 10 + 5 over 2 + 1 + 1 samples
    assert m.sample_avg_idleness == pytest.approx(35.0 / 4.0)
    assert m.sample_coverage == pytest.approx(35.0 / 400.0)
    assert m.never_visited == 1


def test_unvisited_vertex_and_visits_after_the_end():
    m = compute_metrics([(1.0, 0, 0), (3.0, 0, 0), (20.0, 0, 0)], n_vertices=2, duration=5.0)
    assert m.never_visited == 1
    assert m.worst_idleness == pytest.approx(5.0)            # vertex 1 never visited
    # vertex 0 gaps 1, 2, 2 -> 0.5 + 2 + 2; vertex 1 gap 5 -> 12.5; / (2 * 5)
    assert m.time_avg_idleness == pytest.approx(17.0 / 10.0)
    assert m.n_visits == 2


def test_no_samples_gives_empty_sample_metrics():
    m = compute_metrics([(1.0, 0, 0)], n_vertices=1, duration=4.0)
    assert m.sample_avg_idleness is None and m.sample_max_idleness is None
    assert all(v is None for v in m.idleness_percentiles.values())


def test_percentiles_of_samples():
    visits = [(float(t), 0, 0) for t in (0, 1, 3, 6, 10)]     # samples 1, 2, 3, 4
    m = compute_metrics(visits, n_vertices=1, duration=10.0)
    assert m.idleness_percentiles["p50"] == pytest.approx(2.5)
    assert m.idleness_percentiles["p99"] == pytest.approx(float(np.percentile([1, 2, 3, 4], 99)))


def test_time_average_matches_a_fine_time_grid():
    rng = np.random.default_rng(3)
    visits = sorted((float(t), 0, int(v)) for t, v in
                    zip(rng.uniform(0, 100, 60), rng.integers(0, 5, 60)))
    m = compute_metrics(visits, n_vertices=5, duration=100.0)
    grid = np.linspace(0, 100, 200001)
    idl = np.zeros((5, grid.size))
    for v in range(5):
        last = np.zeros(grid.size)
        for t, _, w in visits:
            if w == v:
                last[grid >= t] = t
        idl[v] = grid - last
    assert m.time_avg_idleness == pytest.approx(idl.mean(), rel=1e-3)
    assert m.time_avg_max_idleness == pytest.approx(idl.max(axis=0).mean(), rel=1e-3)
    assert m.worst_idleness == pytest.approx(idl.max(), rel=1e-3)


@pytest.mark.parametrize("bad", [dict(n_vertices=0, duration=1.0),
                                 dict(n_vertices=1, duration=-1.0)])
def test_bad_arguments(bad):
    with pytest.raises(ValueError):
        compute_metrics([], **bad)


def test_vertex_outside_graph():
    with pytest.raises(ValueError, match="vertex 3"):
        compute_metrics([(1.0, 0, 3)], n_vertices=2, duration=2.0)


def test_read_visits(tmp_path):
    p = tmp_path / "x_visits.csv"
    p.write_text("Time;Robot;Node\n0.5;0;3\n1.25;1;4\n")
    assert read_visits(str(p)) == [(0.5, 0, 3), (1.25, 1, 4)]
    p.write_text("Time;Robot;Node\n0.5;zero;3\n")
    with pytest.raises(ValueError, match=r"x_visits.csv:2"):
        read_visits(str(p))


def _graph(edges, pos, resolution=1.0):
    G = nx.MultiDiGraph(resolution=resolution, name="t")
    for v, (x, y) in enumerate(pos):
        G.add_node(v, pos=(x, y), x_px=x, y_px=y)
    for a, b, c in edges:
        G.add_edge(a, b, cost_px=c)
        G.add_edge(b, a, cost_px=c)
    return PatrolGraph(G)


def test_held_karp_equals_brute_force():
    rng = np.random.default_rng(7)
    pts = rng.uniform(0, 10, (8, 2))
    D = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    brute = min(sum(D[p[i], p[(i + 1) % 8]] for i in range(8))
                for p in ([0] + list(q) for q in itertools.permutations(range(1, 8))))
    assert _held_karp(D) == pytest.approx(brute)


def test_references_on_a_ring():
    # 12 vertices on a ring, each edge 5 m: best tour 60 m; 3 robots at 1 m/s -> 20 s;
    # a balanced partition into 3 arcs of 4 vertices: each part's closed walk is 2 * 15 m.
    n = 12
    g = _graph([(i, (i + 1) % n, 5.0) for i in range(n)],
               [(math.cos(2 * math.pi * i / n), math.sin(2 * math.pi * i / n)) for i in range(n)])
    L, exact = best_tour_length(g)
    assert exact and L == pytest.approx(60.0)
    r = references(g, 3, speed=1.0)
    assert r.cyclic_idleness == pytest.approx(20.0)
    assert sorted(r.partition_sizes) == [4, 4, 4]
    assert r.partition_idleness == pytest.approx(30.0)
    with pytest.raises(ValueError):
        references(g, 0)


def test_heuristic_tour_on_a_large_graph_is_close_to_the_grid_optimum():
    # 6 x 6 grid with 2 m edges: a Hamiltonian circuit exists, 36 * 2 = 72 m
    idx = {(i, j): 6 * i + j for i in range(6) for j in range(6)}
    edges = [(idx[i, j], idx[i + di, j + dj], 2.0) for (i, j) in idx
             for di, dj in ((1, 0), (0, 1)) if (i + di, j + dj) in idx]
    g = _graph(edges, [(2 * j, 2 * i) for (i, j) in sorted(idx, key=idx.get)])
    L, exact = best_tour_length(g)
    assert not exact
    assert 72.0 - 1e-9 <= L <= 72.0 * 1.05


def test_graph_idleness_series_by_hand():
    from patrolling_sim.monitor.metrics import graph_idleness_series
    t, s = graph_idleness_series([(2.0, 0, 0), (4.0, 1, 1), (6.0, 0, 0)], 2, 10.0, step=2.0)
    assert list(t) == [0, 2, 4, 6, 8, 10]
    # vertex 0 idleness 0,0,2,0,2,4; vertex 1: 0,2,0,2,4,6
    assert list(s) == pytest.approx([0, 1, 1, 1, 3, 5])


def test_failure_impact_on_a_synthetic_curve():
    from patrolling_sim.monitor.metrics import failure_impact
    t = np.arange(0.0, 3601.0)
    # 20 s before the failure at 1200 s; rises linearly to 30 s over 300 s; flat after
    y = np.where(t < 1200, 20.0, np.minimum(30.0, 20.0 + (t - 1200) / 30.0))
    f = failure_impact(t, y, 1200.0, 3600.0, window=600.0, smooth=1.0, band=0.1)
    assert f.before == pytest.approx(20.0)
    assert f.after == pytest.approx(30.0)
    # within 10 % of 30 from 27 s on: 1200 + 210 s
    assert f.settle_time == pytest.approx(211.0, abs=1.0)
    assert f.after > f.before
