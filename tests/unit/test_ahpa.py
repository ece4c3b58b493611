"""AHPA (docs/algorithms/AHPA.md): graph-Voronoi cells by path cost with ties to the lower
robot id, one tour per cell, re-partition when a teammate falls silent and again when it is
heard back; in graph mode with failures and imperfect communication every vertex is still
visited after a failure, the failed robot's former cell included."""
import pytest

from patrolling_sim.algorithms.ahpa import voronoi_cells
from patrolling_sim.algorithms.testing import deliver, make_strategy, walk
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.monitor.metrics import read_visits
from patrolling_sim.algorithms.testing import graph_from


#: a corridor 0-1-2-3-4-5-6 (cost 10 per edge) and a dear spur 6-7 (cost 40)
CORRIDOR = graph_from({v: (10 * v, 10) for v in range(8)},
                      {**{(v, v + 1): 10 for v in range(6)}, (6, 7): 40})


def test_cells_by_path_cost_ties_to_the_lower_id():
    # robot 1 on 0, robot 0 on 4: vertex 2 is 20 from both -> robot 0 (lower id)
    cells = voronoi_cells(CORRIDOR, {1: 0, 0: 4})
    assert cells == {0: [2, 3, 4, 5, 6, 7], 1: [0, 1]}
    # path cost, not hops: 7 is one hop from 6 but 40 away; robot 2 on 7 keeps it alone
    cells = voronoi_cells(CORRIDOR, {0: 0, 1: 4, 2: 7})
    assert cells == {0: [0, 1, 2], 1: [3, 4, 5, 6], 2: [7]}
    # two robots on one vertex: the lower id takes the cell, the other's is empty
    assert voronoi_cells(CORRIDOR, {0: 3, 1: 3}) == {0: list(range(8)), 1: []}


def team(graph, starts, params=None):
    """AHPA strategies for robots 0..n-1 started on ``starts``, with their first decision
    and announcements exchanged (each has heard every teammate's seed)."""
    out = [make_strategy("AHPA", graph=graph, robot_id=i, team_size=len(starts),
                         params=params) for i in range(len(starts))]
    for (s, d), v in zip(out, starts):
        s.start(v, 0.0)
        s.next_vertex(0.0)
    strategies = [s for s, _ in out]
    for _, d in out:
        deliver(d.sent, strategies, 1.0)
    for s in strategies:
        s.replan()
    return strategies


def partition(strategies):
    cells = [set(s.cell) for s in strategies]
    assert sum(len(c) for c in cells) == len(set().union(*cells)), "cells overlap"
    return cells


def test_three_cells_cover_the_graph_and_reform_after_a_loss_and_a_rejoin():
    a, b, c = team(CORRIDOR, [0, 3, 6])
    assert partition([a, b, c]) == [{0, 1}, {2, 3, 4}, {5, 6, 7}]
    # every robot's tour covers its cell; the message carries vertex and seed
    assert set(b.cyc) == {2, 3, 4} and b.cyc[0] == 3
    # robot 2 falls silent: 0 and 1 drop it and split the corridor between them
    for s in (a, b):
        s.on_teammate_silent(2, 200.0)
        s.on_arrival(s.next, 200.0)
        s.next_vertex(200.0)
    assert partition([a, b]) == [{0, 1}, {2, 3, 4, 5, 6, 7}]
    assert 2 not in b.alive and b.replans == 3       # alone, with the team, without 2
    # it is heard again: the three cells are back
    c.current = 6
    c.send_results(300.0)
    deliver(c.driver.sent[-1:], [a, b], 300.0)
    for s in (a, b):
        s.on_arrival(s.next, 301.0)
        s.next_vertex(301.0)
    assert partition([a, b, c]) == [{0, 1}, {2, 3, 4}, {5, 6, 7}]


def test_current_seeds_regrow_the_cells_from_where_the_survivors_stand():
    a, b, c = team(CORRIDOR, [0, 3, 6], params={"ahpa_seeds": "current"})
    b.current = 5                              # robot 1 has walked to 5 meanwhile
    b.on_teammate_silent(2, 200.0)
    b.replan()
    assert b.seeds[1] == 5 and set(b.cell) == {3, 4, 5, 6, 7}
    assert b.algorithm_params == "current,3"
    with pytest.raises(ValueError, match="ahpa_seeds"):
        make_strategy("AHPA", graph=CORRIDOR, params={"ahpa_seeds": "centre"})


def test_a_lone_robot_tours_the_whole_graph():
    s, d = make_strategy("AHPA", graph=CORRIDOR)
    goals = walk(s, d, 3, 30)
    assert set(goals) == set(range(8))
    assert all(CORRIDOR.arc_cost(x, y) is not None for x, y in zip(goals, goals[1:]))
    assert all(m[1] == 56 and len(m) == 4 for m in d.sent)


def run(tmp_path, **kw):
    kw.setdefault("map", "grid")
    kw.setdefault("params", {"teammate_timeout": 60.0})
    sim = GraphSimulator(GraphSimConfig(results_dir=str(tmp_path), alg="AHPA", **kw))
    sim.run()
    return sim, read_visits(sim.prefix + "_visits.csv")


@pytest.mark.parametrize("comm", ["perfect", "bernoulli:p=0.2;delay=uniform:0.1,0.6"])
def test_graph_mode_recovers_the_failed_robots_cell(tmp_path, comm):
    """grid, 5 robots, robot 2 fails for good at 600 s: once the survivors have dropped it
    (silence of 60 s, checked every 10 s) their cells cover every vertex without it, and
    every vertex -- robot 2's former cell too -- is visited again."""
    sim, visits = run(tmp_path, robots=5, duration=1500, seed=2, attrition="2@600", comm=comm)
    assert sim.termination == "TIMEOUT" and sim.monitor.failures == [[2, 600.0, None]]
    lost_cell = set(sim.robots[2].core.strategy.cell)
    assert lost_cell
    survivors = [sim.robots[r].core.strategy for r in (0, 1, 3, 4)]
    assert all(s.alive == {0, 1, 3, 4} for s in survivors)
    cells = partition(survivors)
    assert set().union(*cells) == set(range(sim.g.n))
    after = {v for t, r, v in visits if t > 700.0}
    assert after == set(range(sim.g.n)) and lost_cell <= after
    assert not [t for t, r, _ in visits if r == 2 and t > 600.0]


def test_graph_mode_repaired_robot_rejoins(tmp_path):
    sim, visits = run(tmp_path, robots=4, duration=1500, seed=1, attrition="1@400+400")
    strategies = [r.core.strategy for r in sim.robots]
    assert all(s.alive == {0, 1, 2, 3} for s in strategies)
    assert set().union(*partition(strategies)) == set(range(sim.g.n))
    assert all(s.replans >= 3 for s in (strategies[0], strategies[2], strategies[3]))
    assert [t for t, r, _ in visits if r == 1 and t > 850.0]
