"""DTASSI (docs/algorithms/DTASSI.md): sequential single-item auctions whose bid is the cost
of a tour through the robot's own tasks, without DTAP's partition, on small hand-made graphs."""
import pytest

from patrolling_sim.algorithms.testing import RecordingDriver, deliver, make_strategy
from patrolling_sim.common.protocol import MSG_DTA_IDLENESS, MSG_SSI_BID, MSG_SSI_TASK_REQUEST
from patrolling_sim.model.graph import PatrolGraph, parse_graph


class WaitingDriver(RecordingDriver):
    """A life cycle that waits for a pending decision (as graph mode and ROS mode do)."""
    accepts_pending_decision = True


def graph_of(xs, edges):
    """A .graph with vertices at ``xs`` (px, on one row) and undirected ``edges`` {(a, b):
    cost}."""
    nb = {v: [] for v in range(len(xs))}
    for (a, b), c in edges.items():
        nb[a].append((b, c))
        nb[b].append((a, c))
    lines = [str(len(xs)), "100", "100", "0.1", "0", "0", ""]
    for v, x in enumerate(xs):
        lines += [str(v), str(x), "50", str(len(nb[v]))]
        for w, c in nb[v]:
            lines += [str(w), "N", str(c)]
        lines.append("")
    return PatrolGraph(parse_graph("\n".join(lines)))


#: 0 - 1 - 2 - 3 - 4, every edge 10
LINE = graph_of([0, 10, 20, 30, 40], {(0, 1): 10, (1, 2): 10, (2, 3): 10, (3, 4): 10})
#: a hub 1 with the spokes 0, 2, 3 (10 each) and 3 - 4 (10)
T = graph_of([0, 10, 20, 10, 10], {(0, 1): 10, (1, 2): 10, (1, 3): 10, (3, 4): 10})


def robot(alg, g, rid=0, n=2, driver=None):
    return make_strategy(alg, graph=g, robot_id=rid, team_size=n,
                         driver=driver or WaitingDriver())


def sent(driver, kind):
    return [m for m in driver.sent if m[1] == kind]


def test_a_teammates_better_bid_wins_and_the_auctioneer_picks_another():
    """Robot 1 heads for vertex 3, so it bids 0 for it; robot 0 auctions 3 (the idlest in its
    estimate), loses it to that bid, and auctions and wins its next candidate, 2."""
    a, da = robot("DTASSI", LINE, rid=0)
    b, db = robot("DTASSI", LINE, rid=1)
    a.start(0, 0.0)
    b.start(4, 0.0)
    deliver(da.sent + db.sent, [a, b], 0.0)
    for s, d in ((a, da), (b, db)):
        d.t = 1.0
        d.run_due_timers()                      # both first auctions end after 1 s
    assert (a.next_vertex(1.0), b.next_vertex(1.0)) == (1, 3)
    # robot 1 tells robot 0 that everything but 3 was visited just now
    deliver([[1, MSG_DTA_IDLENESS, 0, 0, 0, 900, 0, 3]], [a], 50.0)
    da.sent.clear()
    da.t = 50.0
    a.send_results(50.0)                        # the auction for the target after 1
    req = sent(da, MSG_SSI_TASK_REQUEST)
    assert [m[2] for m in req] == [3]
    # own bid: the tour 0 -> 1 (next target) -> 3 -> 0
    assert a.tour(3) == [0, 1, 3, 0] and req[0][3] == 10 + 20 + 30
    db.sent.clear()
    deliver(req, [b], 50.0)
    assert sent(db, MSG_SSI_BID) == [[1, MSG_SSI_BID, 3, 0]]    # 3 is its next target
    deliver(db.sent, [a], 50.2)
    assert a.best_bid[3] == (0.0, 1)
    da.t = 51.0
    da.run_due_timers()                         # lost: not adjacent to 1, so no greedy take
    assert a.won is None and [m[2] for m in sent(da, MSG_SSI_TASK_REQUEST)] == [3, 2]
    da.t = 52.0
    da.run_due_timers()                         # nobody outbids it for 2
    assert a.won == 2 and 2 in a.tasks and 3 not in a.tasks


def test_the_bid_is_a_tour_through_the_tasks_in_utility_order():
    """From the next target the tour takes the remaining tasks and v by decreasing U (idle
    first, hops penalised), then returns to the current vertex; the bid sums the legs."""
    s, _ = robot("DTASSI", T)
    s.start(0, 0.0)
    s.current, s.next, s.won = 0, 1, None
    for v in (2, 4):
        s.record_bid(v, 5.0, 0)                 # its own best bids: its tasks
    assert s.tasks == [1, 2, 4]                 # 1: its first auction's bid, kept
    s.gi.values[:] = [0.0, 0.0, 10.0, 0.0, 100.0]
    # from 1: U(4) = 100 - 2*2*5 = 80 beats U(2) = 10 - 10 = 0 and U(3) = -10
    assert s.tour(3) == [0, 1, 4, 3, 2, 0]
    assert s.bid(3) == pytest.approx(10 + 20 + 10 + 20 + 20)
    s.gi.values[2] = 200.0                      # now 2 is the idlest: it comes first
    assert s.tour(3) == [0, 1, 2, 4, 3, 0]
    assert s.bid(3) == pytest.approx(10 + 10 + 30 + 10 + 20)
    assert s.bid(1) == 0.0 and s.tour(1) == []  # already its next target


def test_first_auction_tour_starts_at_the_best_candidate():
    """Before the first target is known the tour starts with the task (or v) of highest U
    from the current vertex."""
    s, d = robot("DTASSI", LINE)
    s.start(0, 0.0)                             # auction for 1 running, no next target
    assert s.next is None and sent(d, MSG_SSI_TASK_REQUEST)[0][2:] == [1, 20]
    s.gi.values[:] = [0.0, 0.0, 0.0, 0.0, 500.0]
    assert s.tour(2) == [0, 2, 0]
    s.record_bid(4, 3.0, 0)                     # tasks now 4 and 1 (its running auction's)
    assert s.tasks == [1, 4]
    assert s.tour(2) == [0, 4, 2, 1, 0] and s.bid(2) == pytest.approx(40 + 20 + 10 + 10)


def test_no_partition_unlike_dtap():
    """DTAP bids the path cost from v to its partition's centre times (1 + |tasks|), the same
    wherever the robot stands; DTASSI has no centre: its bid follows the robot (the tour
    starts and ends at its current vertex), and its task count does not lengthen its
    auctions (1 s; DTAP's 1 + 0.1 per task)."""
    bids = {}
    for alg in ("DTAP", "DTASSI"):
        s, d = robot(alg, LINE)
        s.start(0, 0.0)
        d.t = 1.0
        d.run_due_timers()
        s.won = s.next = None
        for v in (0, 1):
            s.record_bid(v, 1.0, 0)             # tasks {0, 1}: DTAP's centre stays 0
        assert s.tasks == [0, 1]
        s.gi.values[:] = [0.0, 10.0, 10.0, 10.0, 10.0]
        bids[alg] = []
        for here in (0, 4):
            s.current = here
            bids[alg].append(s.bid(3))
        assert s.auction_wait() == pytest.approx({"DTAP": 1.2, "DTASSI": 1.0}[alg])
    assert bids["DTAP"] == [30.0 * 3, 30.0 * 3]
    # from 0: 0 -> 1 -> 3 -> 0 (tasks by U: 1 first); from 4: 4 -> 3 -> 1 -> 0 -> 4
    assert bids["DTASSI"] == [10 + 20 + 30, 10 + 20 + 10 + 40]


def test_greedy_take_of_an_adjacent_very_idle_vertex():
    """Lost auction, but the vertex is one hop away, far idler than the rest (above mean +
    2 SD) and nobody's bid for it is 0: taken anyway, without becoming a task."""
    g = graph_of(list(range(0, 90, 10)), {(i, i + 1): 10 for i in range(8)})
    s, d = robot("DTASSI", g)
    s.start(0, 0.0)
    s.gi.values[:] = 0.0
    s.gi.values[1] = 500.0
    s.record_bid(1, 1.0, 1)                     # robot 1's bid (1) beats ours (20)
    d.t = 1.0
    d.run_due_timers()
    assert s.won == 1 and 1 not in s.tasks


def test_registered_with_the_originals_parameters():
    s, _ = robot("DTASSI", LINE)
    assert s.name == "DTASSI" and s.algorithm_params == "3,1,0,-2,0,0"
