"""DTAP and DTASSI starve a vertex as the original does (docs/algorithms/DTAP.md, "Where it
starves a vertex"): a zero bid is never beaten, so a robot that loses every auction stands
frozen on a vertex it never reports and that no teammate can win. Graph mode (messages at
once) on a hand-made path 0 - 1 - 2 - 3, every edge 20 px."""
import pytest

from patrolling_sim.algorithms.testing import graph_from
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator

PATH = graph_from({0: (10, 50), 1: (30, 50), 2: (50, 50), 3: (70, 50)},
                  {(0, 1): 20, (1, 2): 20, (2, 3): 20})


def run(alg, starts, duration=600):
    """(the simulator, the number of reported visits of each vertex, the time of the last
    report) of one seed-0 run, from the monitor's tables."""
    sim = GraphSimulator(GraphSimConfig(map="grid", robots=len(starts), alg=alg,
                                        duration=duration, seed=0),
                         start_vertices=starts, pgraph=PATH)
    sim.run(write=False)
    counts = [k + 1 for k in sim.monitor.visits]        # the monitor starts them at -1
    return sim, counts, max(sim.monitor.last_report.values())


@pytest.mark.parametrize("alg", ["DTAP", "DTASSI"])
def test_one_robot_per_vertex_makes_no_visit(alg):
    """Each robot bids 0 for the vertex it stands on (DTAP: its centre; DTASSI: the tour from
    there to there) and every other vertex is a teammate's: once the first auctions are over
    (a robot may win a neighbour whose owner has not started yet), every auction is lost and
    nothing is reported for the rest of the 600 s, though the robots keep auctioning."""
    sim, counts, last = run(alg, [0, 1, 2, 3])
    assert sum(counts) <= 2 and last < 5.0
    assert sim.messages_sent > 1000


def test_a_robot_that_loses_its_first_auction_hides_its_start_vertex():
    """Robots 0 and 1 lose their first auctions (vertex 1 and vertex 0 are each other's
    zero, 2 and 3 robot 2's): they stand on 0 and 1 for the whole run, never reported, while
    robot 2 shuttles between 2 and 3. Robot 1 holds vertex 1 with a zero in every table."""
    sim, counts, _ = run("DTASSI", [0, 1, 2])
    assert counts[0] == counts[1] == 0
    assert counts[2] > 50 and counts[3] > 50
    strategies = [sim.robots[r].core.strategy for r in range(3)]
    assert [s.current for s in strategies[:2]] == [0, 1]
    assert all(s.best_bid[1] == (0.0, 1) for s in strategies)


def test_two_robots_on_four_vertices_visit_every_vertex():
    """The contrast: with vertices to spare nobody freezes."""
    for alg in ("DTAP", "DTASSI"):
        _, counts, _ = run(alg, [0, 3])
        assert min(counts) > 50, alg
