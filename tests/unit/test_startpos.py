"""--initpos optimised (startpos.py) -- start vertices chosen for the algorithm."""
import numpy as np
import pytest

from patrolling_sim.common import paths
from patrolling_sim.model.graph import PatrolGraph, parse_graph
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.planning.routes import route_cost
from patrolling_sim.runner.config import ExperimentConfig
from patrolling_sim.startpos.optimised import (kcentre_start_vertices, optimised_start_vertices,
                                               probe_route, strategy_kind)


def worst_idleness(alg, n, initpos, duration=1500.0):
    """Worst idleness in the abstract world of the original's reference runs: straight-line
    travel at 1 m/s, no goal wait, no interference."""
    cfg = GraphSimConfig(map="grid", robots=n, alg=alg, duration=duration, seed=1,
                         initpos=initpos, gwait=0.0, speed=1.0, travel="euclidean",
                         interference=False)
    return GraphSimulator(cfg).run(write=False).global_max


def test_cyclic_tour_grid_four_robots_near_even_spacing():
    # CGG_TSP follows one closed tour: evenly spaced robots meet L / (k v) at worst
    pg = PatrolGraph.load(paths.map_files("grid")[1])
    L = route_cost(pg, probe_route(pg, "CGG_TSP", 4, "grid", 0)) * pg.resolution
    opt = worst_idleness("CGG_TSP", 4, "optimised")
    assert opt <= 1.15 * L / 4, (opt, L)
    assert worst_idleness("CGG_TSP", 4, "default") > 2 * L / 4     # the bunched start it fixes


def test_original_cgg_route_grid_four_robots():
    # the original's CGG walks a Hamiltonian path forth and back and starts every robot at
    # the first occurrence of its vertex: only the forward half can hold a start, so the
    # best spread is about twice L / (k v) -- still better than the default start
    pg = PatrolGraph.load(paths.map_files("grid")[1])
    L = route_cost(pg, probe_route(pg, "CGG", 4, "grid", 0)) * pg.resolution
    opt = worst_idleness("CGG", 4, "optimised")
    assert opt <= worst_idleness("CGG", 4, "default")
    assert opt <= 2.3 * L / 4, (opt, L)


@pytest.mark.parametrize("n", [2, 8])
@pytest.mark.parametrize("alg", ["CGG", "CGG_TSP", "MSP"])
def test_optimised_no_worse_than_default_on_grid(alg, n):
    assert worst_idleness(alg, n, "optimised") <= worst_idleness(alg, n, "default") + 1e-6


def test_kinds_and_msp_part_centres():
    assert strategy_kind("CGG") == "cyclic" and strategy_kind("MSP") == "partition"
    assert strategy_kind("CR") == "other"
    pg = PatrolGraph.load(paths.map_files("grid")[1])
    from patrolling_sim.algorithms.msp import msp_route
    verts, method = optimised_start_vertices(pg, 4, "MSP", "grid")
    assert method.startswith("one per part")
    for i, v in enumerate(verts):          # robot i stands in the part MSP gives robot i
        assert v in msp_route(pg, "grid", 4, i)[0]


def _path_graph(n, cost=10):
    lines = [f"{n} 100 100 0.1 0 0"]
    for v in range(n):
        nb = [w for w in (v - 1, v + 1) if 0 <= w < n]
        lines.append(f"{v} {v * cost} 0 {len(nb)} " + " ".join(f"{w} E {cost}" for w in nb))
    return PatrolGraph(parse_graph("\n".join(lines)))


def test_kcentre_exact_and_heuristic():
    pg = _path_graph(9)
    # 9 vertices on a line, 3 centres: 1, 4, 7 (every vertex within one edge)
    assert sorted(kcentre_start_vertices(pg, 3, np.ones(9, bool))) == [1, 4, 7]
    big = _path_graph(60)
    v = kcentre_start_vertices(big, 6, np.ones(60, bool))     # C(60, 6) > exact limit
    d = big.dist[v].min(axis=0).max()
    assert d <= 2 * 50                                       # optimum is 50 (5 edges)
    verts, method = optimised_start_vertices(pg, 3, "CR", "line")
    assert method == "k-centre" and sorted(verts) == [1, 4, 7]


def test_runner_config_accepts_optimised(tmp_path):
    cfg = ExperimentConfig(map="grid", robots=4, alg="CGG", initpos="optimised",
                           results_dir=str(tmp_path)).validate()
    pos = cfg.start_positions()
    pg = PatrolGraph.load(paths.map_files("grid")[1])
    want, _ = optimised_start_vertices(pg, 4, "CGG", "grid")
    assert [pg.nearest_vertex(x, y) for x, y in pos] == want


def test_graph_mode_writes_start_poses(tmp_path):
    cfg = GraphSimConfig(map="grid", robots=3, alg="CR", duration=50, initpos="optimised",
                         results_dir=str(tmp_path))
    sim = GraphSimulator(cfg)
    sim.run()
    lines = open(sim.prefix + "_start_poses.txt").read().splitlines()
    assert lines[0] == "# start poses: --initpos optimised"
    assert [int(l.split()[3]) for l in lines[2:]] == sim.start_vertices
