"""The strategies: rules (docs/fidelity.md), messages, determinism, routes and partitions."""
import math
import random

import pytest

from patrolling_sim.common import paths
from patrolling_sim.algorithms import REGISTRY, StrategyContext, create, names
from patrolling_sim.algorithms.cgg import rotate_to
from patrolling_sim.algorithms.gbs import gbs_params, gbs_probability
from patrolling_sim.algorithms.msp import msp_route
from patrolling_sim.algorithms.testing import (RecordingDriver, deliver, load_graph,
                                               make_strategy, walk)
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.planning.routes import balanced_partition, closed_route, route_cost

#: the original's short names (each must stay registered): its launcher's eleven and DTASSI
ORIGINAL = ["RAND", "CR", "HCR", "HPCC", "CGG", "MSP", "GBS", "SEBS", "CBLS", "DTAG", "DTAP",
            "DTASSI"]
#: every registered algorithm, the originals and this project's improvements
ALL = names()


def graph(name):
    return load_graph(name)


def make(alg, mapname="grid", rid=0, n=1, seed=0, params=None):
    return make_strategy(alg, mapname, rid, n, seed, params)


def test_registry_has_the_eleven():
    assert set(ORIGINAL) <= set(names()) and names() == sorted(REGISTRY)
    assert "CGG_TSP" in names()                 # our improvement, under its own name
    with pytest.raises(KeyError, match="unknown algorithm 'FOO'.*CGG"):
        create("FOO", None)


@pytest.mark.parametrize("alg", ALL)
@pytest.mark.parametrize("mapname", ["grid", "example", "1r5", "DIAG_labs"])
def test_every_algorithm_patrols_every_vertex(alg, mapname):
    s, d = make(alg, mapname, seed=3)
    g = graph(mapname)
    goals = walk(s, d, 0, 40 * g.n)
    assert set(goals) == set(range(g.n)), f"{alg} never reached {set(range(g.n)) - set(goals)}"


@pytest.mark.parametrize("alg", ALL)
def test_deterministic_for_a_seed(alg):
    a = walk(*make(alg, "example", seed=5), 3, 60)
    b = walk(*make(alg, "example", seed=5), 3, 60)
    assert a == b


@pytest.mark.parametrize("alg", ["RAND", "CR", "HCR", "GBS", "SEBS", "CBLS", "CGG"])
def test_neighbour_steps(alg):
    g = graph("cumberland")
    s, d = make(alg, "cumberland", seed=1)
    goals = walk(s, d, 7, 200)
    for a, b in zip([7] + goals, goals):
        assert g.arc_cost(a, b) is not None, f"{alg}: {a}->{b} not adjacent"


def test_cr_takes_the_idlest_neighbour():
    s, d = make("CR")
    s.start(6, 0.0)                  # grid vertex 6: neighbours 1, 5, 7, 11
    s.last_visit = [0.0] * 25
    s.last_visit[5] = -50.0          # oldest visit -> highest idleness
    s.update_idleness(10.0)
    assert s.choose_next(10.0) == 5


def test_hcr_trades_distance_against_idleness():
    g = graph("example")
    u = next(v for v in range(g.n)
             if len({g.arc_cost(v, w) for w in g.neighbor_ids(v)}) > 1 and g.degree(v) >= 2)
    nbrs = g.neighbor_ids(u)
    s, d = make("HCR", "example")
    s.start(u, 0.0)
    s.idleness = [0.0] * g.n         # idleness term 0 -> the nearest neighbour wins
    assert s.choose_next(0.0) == min(nbrs, key=lambda w: (g.arc_cost(u, w), w))
    far = max(nbrs, key=lambda w: g.arc_cost(u, w))
    s.idleness[far] = 1000.0         # now the idle far one wins: 1 + (dmax-dfar)/dmax >= others
    assert s.choose_next(0.0) == far


def test_hpcc_follows_adjacent_path_to_a_far_idle_goal():
    g = graph("grid")
    s, d = make("HPCC")
    s.start(0, 0.0)
    s.idleness = [0.0] * 25
    s.idleness[24] = 500.0           # far corner, very idle
    first = s.next_vertex(0.0)
    route = [first] + list(s.route)
    assert route[-1] == 24
    for a, b in zip([0] + route, route):
        assert g.arc_cost(a, b) is not None


def test_gbs_formula_and_table():
    assert gbs_params("grid", 4) == (0.1, 11.15, 1.0)
    assert gbs_params("cumberland", 12) == (0.1, 63.5, 50.0)
    assert gbs_params("broughton", 4) == (0.1, 100.0, 1.0)
    assert gbs_probability(0.0, 0.1, 100) == pytest.approx(0.1)
    assert gbs_probability(50.0, 0.1, 100) == pytest.approx(0.1 * math.exp(math.log(10) * 0.5))
    assert gbs_probability(100.0, 0.1, 100) == 1.0


def test_gbs_shares_idleness():
    s, d = make("GBS", n=2)
    s.start(0, 0.0)
    s.next_vertex(0.0)
    assert not d.sent                           # nothing is sent while deciding
    s.send_results(0.0)
    assert d.sent[-1] == [0, 31, 0]
    s.on_message([1, 31, 7], 20.0)
    assert s.last_visit[7] == 20.0 and s.idleness[7] == 0.0
    s.update_idleness(20.0)                     # refreshed at the next decision
    assert s.idleness[8] == pytest.approx(20.0)


def test_sebs_avoids_teammates_intentions():
    s, d = make("SEBS", n=3, rid=0)
    s.start(6, 0.0)
    s.last_visit = [0.0] * 25
    s.update_idleness(30.0)          # all neighbours equally idle
    s.on_message([1, 32, 0, 5], 30.0)
    s.on_message([2, 32, 2, 7], 30.0)
    s.on_message([1, 32, 3, 11], 30.0)
    # 0 and 2 were just visited (not neighbours of 6); 11 and 7 are intended, 5 too (overwritten?)
    assert s.intention == {1: 11, 2: 7}
    assert s.choose_next(30.0) in (1, 5)
    v = s.next_vertex(30.0)
    s.send_results(30.0)
    assert d.sent[-1] == [0, 32, 6, v]
    assert s.algorithm_params == "0.1,100"


def test_cbls_learns_and_stays_bounded():
    s, d = make("CBLS", "example", n=1, seed=2)
    walk(s, d, 0, 400)
    vals = list(s.real_hist.values())
    assert min(vals) >= 0.5 and max(vals) <= 2.0
    assert any(abs(x - 1.0) > 1e-6 for x in vals), "no arc weight was ever learnt"
    assert all(m[1] == 32 and len(m) == 4 for m in d.sent)


def test_cgg_route_is_short_and_closed_on_grid():
    g = graph("grid")
    r = closed_route(g)
    assert r[0] == r[-1] and set(r) == set(range(25))
    assert len(r) - 1 == 26
    assert route_cost(g, r) * g.resolution == pytest.approx(148.2)
    rr = rotate_to(r, 12)
    assert rr[0] == rr[-1] == 12 and sorted(rr[:-1]) == sorted(r[:-1])


@pytest.mark.parametrize("mapname", ["1r5", "DIAG_labs", "ctcv"])
def test_cgg_route_on_trees_is_the_double_traversal(mapname):
    g = graph(mapname)
    r = closed_route(g)
    total = sum(g.arc_cost(u, w) for u in range(g.n) for w in g.neighbor_ids(u))
    assert route_cost(g, r) == pytest.approx(total)     # each edge once in each direction


def test_cgg_robots_share_the_route_from_their_start():
    a, _ = make("CGG", rid=0, n=2)
    b, _ = make("CGG", rid=1, n=2)
    a.start(0, 0.0)
    b.start(12, 0.0)
    assert rotate_to(a.route, 12) == b.route


def test_msp_uses_valid_files_and_replaces_stale_ones():
    g = graph("grid")
    r, src = msp_route(g, "grid", 4, 1)
    assert src.endswith("grid_4_1") and r[0] == r[-1]
    ex = graph("example")
    routes = [msp_route(ex, "example", 4, i) for i in range(4)]
    assert all(src == "computed" for _, src in routes)          # shipped files are stale
    covered = set()
    for r, _ in routes:
        assert r[0] == r[-1]
        for a, b in zip(r, r[1:]):
            assert a == b or ex.arc_cost(a, b) is not None
        covered |= set(r)
    assert covered == set(range(ex.n))


@pytest.mark.parametrize("mapname", ["example", "cumberland", "broughton", "DIAG_floor1"])
@pytest.mark.parametrize("k", [2, 3, 5, 8])
def test_balanced_partition(mapname, k):
    g = graph(mapname)
    parts = balanced_partition(g, k)
    assert len(parts) == k
    flat = [v for p in parts for v in p]
    assert sorted(flat) == list(range(g.n))                    # disjoint cover
    sizes = [len(p) for p in parts]
    assert max(sizes) <= 2.5 * g.n / k + 2, sizes
    for p in parts:
        r = closed_route(g, p)                                 # raises if not connected
        assert set(r) == set(p)


def test_dtag_message_and_conflict():
    g = graph("grid")
    s, d = make("DTAG", rid=1, n=2)
    s.start(0, 0.0)
    v = s.next_vertex(10.0)
    s.send_results(10.0)
    msg = d.sent[-1]
    assert msg[:2] == [1, 40] and len(msg) == g.n + 3 and msg[-1] == v
    # own goal sent as 0, the current vertex zeroed at the decision, the rest 100 s + 10 s
    assert msg[2 + v] == 0 and msg[2 + 0] == 0 and msg[2 + 24] == 1100
    assert s.algorithm_params == "1,-0.75,-5"
    other = [0, 40] + [0] * g.n + [v]
    s.on_message(other, 11.0)                   # robot 0 heads to my goal: I yield
    assert d.redirects and d.redirects[-1] != v and s.next == d.redirects[-1]


def test_dtap_auction_between_two_robots():
    """Two DTAP robots on one message bus: every auctioned vertex ends with one best bidder
    and the robots do not pick the same next target."""
    g = graph("grid")
    bus = []

    class BusDriver(RecordingDriver):
        def __init__(self, rid):
            super().__init__()
            self.rid = rid

        def send(self, data):
            super().send(data)
            bus.append(list(data))

    drivers = [BusDriver(0), BusDriver(1)]
    bots = [create("DTAP", StrategyContext(g, i, 2, "grid", random.Random(i), drivers[i], {}))
            for i in range(2)]
    bots[0].start(0, 0.0)
    bots[1].start(24, 0.0)
    t = 0.0
    for b in bots:
        b.next_vertex(t)
        b.send_results(t)
    for step in range(200):
        t += 0.5
        while bus:
            m = bus.pop(0)
            for b in bots:
                if b.id != m[0]:
                    b.on_message(m, t)
        for b, d in zip(bots, drivers):
            d.t = t
            due = [x for x in d.timers if x[0] <= t]
            d.timers = [x for x in d.timers if x[0] > t]
            for _, fn in due:
                fn()
        if step % 6 == 5:                       # each robot reaches its target every 3 s
            for b in bots:
                b.on_arrival(b.next, t)
                b.next_vertex(t)
                b.send_results(t)
    kinds = {m[1] for d in drivers for m in d.sent}
    assert {40, 41}.issubset(kinds)
    assert bots[0].algorithm_params == "3,1,0,-2,0,0"
    assert bots[0].won is None or bots[0].won != bots[1].won or bots[0].won is None


@pytest.mark.parametrize("mapname", ["grid", "example", "cumberland", "1r5", "broughton",
                                     "DIAG_labs", "DIAG_floor1", "ctcv", "move_base_arena"])
def test_cgg_route_within_10_percent_of_best_found(mapname):
    """The shared CGG route is a closed walk covering every vertex, at most 1.1 x the best
    closed walk a harder search finds (more restarts, other seeds)."""
    from patrolling_sim.planning.routes import tsp_tour
    g = graph(mapname)
    r = closed_route(g)
    assert r[0] == r[-1] and set(r) == set(range(g.n))
    for a, b in zip(r, r[1:]):
        assert g.arc_cost(a, b) is not None
    verts = list(range(g.n))
    best = min(
        sum(g.dist[t[i], t[(i + 1) % len(t)]] for i in range(len(t)))
        for t in (tsp_tour(g.dist, verts, seed=s, restarts=6 if g.n > 100 else 16)
                  for s in ((7,) if g.n > 100 else (7, 99, 2024))))
    assert route_cost(g, r) <= 1.1 * best + 1e-6


def test_hpcc_goal_is_the_formula_argmax_with_random_ties():
    """The vectorised goal choice is the documented formula's argmax, ties broken with the
    robot's generator exactly as argmax_random does (same draws, same result)."""
    from patrolling_sim.algorithms.base import argmax_random
    g = graph("cumberland")
    rng = random.Random(5)
    for trial in range(40):
        s, _ = make("HPCC", "cumberland", seed=trial)
        s.start(trial % g.n, 0.0)
        u = s.current
        s.idleness = [float(rng.choice([0.0, 10.0, 50.0, rng.uniform(0, 300)]))
                      for _ in range(g.n)]
        cands = [v for v in range(g.n) if v != u and g.dist[u, v] < float("inf")]
        dmax = max(g.dist[u, v] for v in cands)
        imax = max(s.idleness[v] for v in cands)
        twin = random.Random()
        twin.setstate(s.rng.getstate())
        want = argmax_random(cands, lambda v: (dmax - g.dist[u, v]) / dmax
                             + (s.idleness[v] / imax if imax > 0 else 0.0), twin)
        route = s._plan()
        assert route[-1] == want
        assert s.rng.getstate() == twin.getstate()


def test_dtap_task_set_and_centre_follow_the_bids():
    """DTAP's tasks are the vertices whose best bid is its own; whenever they change the
    centre is recomputed as the original does: the current vertex, or a task other than the
    old centre with a strictly smaller summed path cost to all tasks."""
    g = graph("cumberland")
    s, _ = make("DTAP", "cumberland", rid=1, n=3)
    s.start(0, 0.0)
    assert s.center == 0                         # the start vertex
    rng = random.Random(3)
    for _ in range(400):
        v = rng.randrange(g.n)
        old_tasks, old_center = s.tasks, s.center
        s.record_bid(v, rng.choice([0.0, 5.0, rng.uniform(0, 500)]), rng.randrange(3))
        tasks = sorted(k for k, (_, r) in s.best_bid.items() if r == s.id)
        assert s.tasks == tasks
        if tasks != old_tasks:
            want, best = s.current, sum(g.dist[s.current, t] for t in tasks)
            for c in tasks:
                d = sum(g.dist[c, t] for t in tasks)
                if c != old_center and d < best:
                    want, best = c, d
            assert s.center == want
        else:
            assert s.center == old_center


@pytest.mark.parametrize("alg", ["CGG", "CGG_TSP", "MSP", "MSP_BAL"])
def test_route_followers_build_their_route_before_go(alg, monkeypatch):
    """prepare() (called when the robot becomes ready, before GO) builds the route, as the
    original's agents do in their init; start() at GO only uses it. In ROS mode the clock
    runs while an agent computes: a route built at GO kept CGG_TSP's robots on their start
    vertices for 12 simulated seconds at x30 (grid, 4 robots)."""
    s, d = make(alg, rid=1, n=4, params={"start_vertices": [0, 13, 20, 11]})
    reference, _ = make(alg, rid=1, n=4, params={"start_vertices": [0, 13, 20, 11]})
    s.prepare(13)
    calls = []
    monkeypatch.setattr(type(s), "build_route", lambda self, v: calls.append(v))
    s.start(13, 0.0)
    monkeypatch.undo()
    assert calls == []
    reference.start(13, 0.0)                    # without prepare: built at start, the same
    assert s.route == reference.route
    assert [s.next_vertex(0.0) for _ in range(5)] == [reference.next_vertex(0.0)
                                                      for _ in range(5)]
    # prepared for another vertex (never in practice): built again at start
    other, _ = make(alg, rid=1, n=4, params={"start_vertices": [0, 13, 20, 11]})
    other.prepare(0)
    other.start(13, 0.0)
    assert other.route == reference.route


@pytest.mark.parametrize("alg", ["DTAG", "DTAP", "DTASSI"])
def test_dta_strategies_compute_their_path_table_before_go(alg):
    g = PatrolGraph.load(paths.map_files("cumberland")[1])     # a graph of its own
    s = create(alg, StrategyContext(g, 0, 2, "cumberland", random.Random(0), RecordingDriver(), {}))
    assert g._dist is None
    s.prepare(3)
    assert g._dist is not None


def test_public_driver_delivers_to_teammates_and_checks_payloads():
    """patrolling_sim.algorithms.testing: deliver() hands each message to every strategy but
    its sender; RecordingDriver refuses a payload outside int16."""
    a, da = make_strategy("GBS", "grid", robot_id=0, team_size=2, seed=1)
    b, _ = make_strategy("GBS", "grid", robot_id=1, team_size=2, seed=1)
    walk(a, da, 0, 3)
    assert da.sent and all(m[0] == 0 for m in da.sent)
    before = list(b.last_visit)
    assert deliver(da.sent, [a, b], da.t) == len(da.sent)
    assert b.last_visit != before                    # b learnt a's visits; a got nothing
    with pytest.raises(ValueError, match="int16"):
        RecordingDriver().send([0, 31, 40000])
