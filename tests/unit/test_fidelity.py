"""Fidelity to the original patrolling_sim (docs/fidelity.md).

1. Graph mode against the original's own runs (tests/unit/data/original_runs/, README
   there): grid, 4 robots at the shipped start poses, the runs' duration, 5 seeds; every
   expected figure is read from the original's result files.
2. One test per known rule of the original, on small hand-made graphs.
"""
import random
import statistics

import numpy as np
import pytest

import fidelity_common as fc
from patrolling_sim.algorithms import StrategyContext, create, names
from patrolling_sim.algorithms.base import Driver
from patrolling_sim.common.protocol import INT16_CAP
from patrolling_sim.algorithms.dta_common import path_hops
from patrolling_sim.algorithms.dtap import int16_payload
from patrolling_sim.algorithms.gbs import gbs_params
from patrolling_sim.planning.routes import CRand, hamiltonian_route
from patrolling_sim.algorithms.testing import graph_from

SEEDS = range(5)
#: tolerances of the comparison (relative to the mean of the original's runs)
TOL = {"avg": 0.10, "max": 0.25, "visits": 0.10}
METRIC = {"avg": 0, "max": 1, "visits": 2}
#: (algorithm, metric) -> why ours differs from the original on purpose or for a known,
#: documented reason (docs/fidelity.md); strict: the test fails if the difference vanishes
KNOWN = {
    ("RAND", "avg"): "the original reseeds rand() from the wall clock before every draw, so "
                     "decisions within one wall second repeat; ours is a seeded uniform choice",
}


@pytest.fixture(scope="module")
def ours():
    """alg -> [(avg, max, visits)] of our graph-mode runs, computed once per algorithm."""
    cache = {}

    def get(alg):
        if alg not in cache:
            cache[alg] = [fc.run_ours(alg, seed) for seed in SEEDS]
        return cache[alg]
    return get


def _cases(metric):
    out = []
    for alg in fc.reference_algorithms():
        reason = KNOWN.get((alg, metric))
        marks = [pytest.mark.xfail(reason=reason, strict=True)] if reason else []
        out.append(pytest.param(alg, id=alg, marks=marks))
    return out


def _check(ours, alg, metric):
    k = METRIC[metric]
    ref = statistics.mean(r[k] for r in fc.reference_figures(alg))
    got = statistics.mean(r[k] for r in ours(alg))
    assert abs(got - ref) <= TOL[metric] * ref, (
        f"{alg}: mean {metric} {got:.1f} vs the original's {ref:.1f} "
        f"(tolerance {TOL[metric]:.0%})")


def test_reference_data_is_there():
    algs = fc.reference_algorithms()
    assert len(algs) == 12 and "CGG_TSP" not in algs and "DTASSI" in algs
    assert fc.reference_duration() > 0
    assert all(fc.reference_figures(a) for a in algs)


@pytest.mark.parametrize("alg, quiet, loaded_runs", [("DTAP", 20, 12), ("DTASSI", 10, 0)])
def test_original_agent_runs_are_the_originals(alg, quiet, loaded_runs):
    """The further runs of the original's DTAP and DTASSI agents (README of their folder) ran
    with the original's shipped DTA parameters (the agents publish them, the monitor writes
    them into info.csv), over the reference duration, and every robot patrolled."""
    dirs = fc.agent_run_dirs(alg)
    assert len(dirs) >= quiet
    loaded = fc.agent_run_dirs(alg, loaded=True)
    assert len(loaded) >= loaded_runs and len(fc.loaded_agent_figures(alg)) == len(loaded)
    for d in dirs + loaded:
        i = fc.info(d)
        assert (i["algorithm"], i["algorithm_params"]) == (alg, "3,1,0,-2,0,0"), (d, i)
        assert i["termination"] == "TIMEOUT" and i["sim_duration"] >= fc.reference_duration()
        assert not fc.stopped_robots(d)
    assert len(fc.reference_figures(alg)) == len(dirs) + len(fc.run_dirs(alg))


@pytest.mark.parametrize("alg", _cases("avg"))
def test_average_idleness_as_the_original(ours, alg):
    _check(ours, alg, "avg")


@pytest.mark.parametrize("alg", _cases("max"))
def test_maximum_idleness_as_the_original(ours, alg):
    _check(ours, alg, "max")


@pytest.mark.parametrize("alg", _cases("visits"))
def test_visit_count_as_the_original(ours, alg):
    _check(ours, alg, "visits")


def test_start_vertices_are_the_reference_runs():
    """The shipped grid_4 start poses give the vertices the original's robots reported
    first (world_visits.csv of the CGG run)."""
    sim = fc.simulator("CGG", 0)
    d = fc.run_dirs("CGG")[0]
    assert sim.start_vertices == [fc.world_visits(d, r)[0] for r in range(fc.ROBOTS)]


def _visit_log(alg, seed):
    sim = fc.simulator(alg, seed)
    log = []
    visit = sim.monitor.visit

    def recording(rid, v, t):
        log.append((t, rid, v))
        return visit(rid, v, t)
    sim.monitor.visit = recording
    sim.run(write=False)
    return log


def test_cgg_visits_the_originals_route_from_each_start():
    """Every robot's visit sequence equals the original's, visit for visit (as far as both
    runs go)."""
    d = fc.run_dirs("CGG")[0]
    log = _visit_log("CGG", 0)
    for r in range(fc.ROBOTS):
        theirs = fc.world_visits(d, r)
        mine = [v for _, rid, v in sorted(log) if rid == r]
        n = min(len(theirs), len(mine))
        assert n > 90 and mine[:n] == theirs[:n], f"robot {r}"


def test_cgg_route_is_the_originals_hamiltonian_path_walked_back():
    d = fc.run_dirs("CGG")[0]
    robot0 = fc.world_visits(d, 0)
    route = hamiltonian_route(fc.simulator("CGG", 0).g)
    cycle = len(route) - 1
    assert route[0] == route[-1] and route[:cycle] == robot0[:cycle]
    half = route[:(cycle // 2) + 1]
    assert route[cycle // 2:] == half[::-1]          # out and back
    assert len(set(half)) == len(half)                # a Hamiltonian path


def test_c_rand_matches_the_c_library():
    r = CRand(1)
    assert [r.rand() for _ in range(3)] == [1804289383, 846930886, 1681692777]


# -- the original's rules on small hand-made graphs --------------------------------------
class FakeDriver(Driver):
    accepts_pending_decision = False

    def __init__(self):
        self.t, self.sent, self.timers, self.redirects = 0.0, [], [], []

    def now(self):
        return self.t

    def send(self, data):
        self.sent.append(list(data))

    def call_later(self, delay, fn):
        self.timers.append((self.t + delay, fn))

    def redirect(self, vertex):
        self.redirects.append(vertex)

    def advance(self, t):
        self.t = t
        due = sorted((x for x in self.timers if x[0] <= t), key=lambda x: x[0])
        self.timers = [x for x in self.timers if x[0] > t]
        for _, fn in due:
            fn()


class WaitingDriver(FakeDriver):
    accepts_pending_decision = True


#: vertex 0 in the middle: a cheap edge to 1, dearer ones to 2 and 3; 1-2-3 a path
STAR = graph_from({0: (50, 50), 1: (55, 50), 2: (50, 80), 3: (20, 50)},
                  {(0, 1): 5, (0, 2): 30, (0, 3): 30, (1, 2): 40, (2, 3): 40})


def make(alg, g, rid=0, n=1, seed=0, driver=None, mapname="star"):
    d = driver or FakeDriver()
    return create(alg, StrategyContext(g, rid, n, mapname, random.Random(seed), d, {})), d


@pytest.mark.parametrize("alg", ["GBS", "SEBS", "CR"])
def test_first_decision_is_a_tie_on_an_all_zero_table(alg):
    """The original does not refresh its table before its first decision: every gain is 0,
    so GBS/SEBS/CR tie over all neighbours (the cheap edge is not preferred)."""
    firsts = set()
    for seed in range(40):
        s, _ = make(alg, STAR, seed=seed)
        s.start(0, 12.0)
        assert s.idleness == [0.0] * STAR.n
        firsts.add(s.next_vertex(12.0))
    assert firsts == {1, 2, 3}


def test_hcr_first_decision_is_the_cheapest_edge():
    for seed in range(10):
        s, _ = make("HCR", STAR, seed=seed)
        s.start(0, 12.0)
        assert s.next_vertex(12.0) == 1


def test_idleness_counts_from_the_clock_zero():
    """last visits start at 0 (the start vertex at 0.1), not at GO: after GO at 12 s a
    never-visited vertex is 12 s idler than one visited at GO."""
    s, _ = make("CR", STAR)
    s.start(0, 12.0)
    s.next_vertex(12.0)
    s.on_arrival(1, 20.0)
    assert s.idleness[2] == pytest.approx(20.0) and s.idleness[0] == pytest.approx(19.9)


def test_gbs_edge_min_is_the_maps_for_every_team_size():
    assert gbs_params("cumberland", 3) == (0.1, 100.0, 50.0)
    assert gbs_params("example", 5) == (0.1, 100.0, 20.0)
    assert gbs_params("cumberland", 4) == (0.1, 80.74, 50.0)


@pytest.mark.parametrize("alg", [a for a in names() if a not in ("CGG", "CGG_TSP", "MSP")])
def test_messages_are_sent_after_the_decision_only(alg):
    """Deciding and arriving share nothing; the algorithm's state message goes out in
    send_results (after the life cycle's visit report), as the original's order. (DTAP's
    auction messages 41/42 belong to its auctions, which run at any time.)"""
    g = fc.simulator("CR", 0).g
    s, d = make(alg, g, n=2, mapname="grid")

    def shared():
        return [m for m in d.sent if m[1] in (31, 32, 40)]
    s.start(0, 0.0)
    assert s.next_vertex(0.0) is not None and shared() == []
    s.on_arrival(s.next, 6.0)
    s.next_vertex(6.0)
    assert shared() == []
    d.sent.clear()
    s.send_results(6.0)
    if alg in ("GBS", "SEBS", "CBLS", "DTAG", "DTAP", "DTASSI"):
        assert d.sent and d.sent[0][0] == 0 and d.sent[0][1] in (31, 32, 40)


def test_dtag_both_robots_yield_and_replan_from_the_contested_vertex():
    """Crossing messages announcing the same next vertex: each robot gives it up (whatever
    the ids), takes it as its current vertex and re-plans from there."""
    bots = [make("DTAG", STAR, rid=r, n=2)[0] for r in range(2)]
    for b, v in zip(bots, (3, 1)):
        b.start(v, 0.0)
        b.next_vertex(0.0)
    assert bots[0].next == bots[1].next == 0         # both go for the centre
    msgs = []
    for b in bots:
        b.send_results(0.0)
        msgs.append(b.driver.sent[-1])
    bots[0].on_message(msgs[1], 0.5)
    bots[1].on_message(msgs[0], 0.5)
    for b in bots:
        assert b.current == 0 and b.driver.redirects == [b.next] and b.next != 0
    # re-planned from vertex 0: robot 0 (origin at 3) prefers the vertex nearest 3 by path
    # cost from 0, i.e. the same choice as a robot standing on 0
    fresh, _ = make("DTAG", STAR, rid=0, n=2)
    fresh.start(3, 0.0)
    fresh.gi.values[:] = bots[0].gi.values
    fresh.current = 0
    assert fresh.choose_next(0.5) == bots[0].next


def test_dtap_first_goal_only_after_the_auction():
    s, d = make("DTAP", STAR, n=2, driver=WaitingDriver())
    s.start(0, 0.0)
    assert d.sent and d.sent[0][1] == 41               # the first auction is running
    assert s.next_vertex(0.0) is None                  # no goal, no report yet
    d.advance(0.5)
    assert s.next_vertex(0.5) is None and not d.redirects
    d.advance(1.0)                                      # auction over (1 s, no tasks)
    assert d.redirects == [d.sent[0][2]] and s.next == d.sent[0][2]


def test_dtap_arriving_during_an_auction_waits_for_it():
    s, d = make("DTAP", STAR, n=2, driver=WaitingDriver())
    s.start(0, 0.0)
    assert s.next_vertex(0.0) is None
    d.advance(1.0)
    first = s.next
    assert first is not None
    s.send_results(1.0)                                 # report done: next auction runs
    s.on_arrival(first, 1.5)
    assert s.next_vertex(1.5) is None                   # still auctioning
    assert s.current == 0                               # the visit is not taken in yet
    d.advance(2.0)
    assert d.redirects == [first]                      # 1.1 s: one task won already
    d.advance(2.2)
    assert d.redirects[-1] == s.next and s.next != first
    assert s.current == first
    s.send_results(2.2)                                 # the next auction starts from here:
    assert s.gi.values[first] == 0.0                    # the reached vertex zeroed


def test_dtap_hops_on_the_cost_shortest_path():
    """0-1 direct costs 50, 0-2-1 costs 20: the original counts 2 hops from 0 to 1."""
    g = graph_from({0: (0, 0), 1: (10, 0), 2: (5, 5)}, {(0, 1): 50, (0, 2): 10, (2, 1): 10})
    assert path_hops(g)[0, 1] == 2 and g.hops[0, 1] == 1


def test_int16_cap_as_the_original():
    assert int16_payload(32767) == 32767 and int16_payload(32768) == INT16_CAP == 32000
    s, d = make("DTAG", STAR)
    s.start(0, 0.0)
    s.next_vertex(5000.0)
    s.send_results(5000.0)
    assert max(d.sent[-1][2:-1]) == INT16_CAP


def test_cbls_ties_go_to_the_last_cheapest_edge():
    """All-zero table: every posterior ties; the original keeps the last tie whose edge is
    the cheapest (no random draw)."""
    sq = graph_from({0: (50, 50), 1: (60, 50), 2: (50, 60), 3: (40, 50), 4: (50, 40)},
                    {(0, 1): 10, (0, 2): 20, (0, 3): 10, (0, 4): 20})
    for seed in range(5):
        s, _ = make("CBLS", sq, seed=seed)
        s.start(0, 0.0)
        assert s.next_vertex(0.0) == 3


def test_cbls_learns_on_the_refreshed_table():
    """On arrival the whole table is refreshed before the learning step, so the arc to the
    vertex just reached (idleness 0) is punished and the arc to the idlest rewarded."""
    s, _ = make("CBLS", STAR)
    s.start(0, 0.0)
    s.on_arrival(1, 3.0)
    s.next_vertex(3.0)                 # from 1: candidates 0 and 2
    s.on_arrival(2, 10.0)
    s.next_vertex(10.0)                # from 2, decision with H < 1 after learning above
    s.on_arrival(1, 20.0)
    u, cands, H = s.decision if s.decision else (None, None, None)
    assert s.idleness[1] == 0.0 and s.idleness[3] == pytest.approx(20.0)
    # the arc 1->2 (just travelled, now the least idle among 1's candidates) was punished
    assert s.real_hist[(1, 2)] < 1.0 or s.real_hist[(1, 0)] > 1.0


def test_cbls_running_mean_uses_the_table_as_last_refreshed():
    s, _ = make("CBLS", STAR, n=2)
    s.start(0, 0.0)
    s.next_vertex(0.0)
    s.on_arrival(1, 5.0)               # table refreshed at 5 s: idleness[2] = 5
    s.on_message([1, 32, 2, 3], 9.0)   # teammate visits 2 at 9 s
    assert s.avg[2] == pytest.approx(5.0 / 1) and s.nvis[2] == 1


def test_cbls_counts_intentions_only_below_its_local_team_size():
    """The original's CBLS counts a teammate's intention only if the sender's id is below its
    local TEAMSIZE: own id + 1, raised by the positions it has heard."""
    d = FakeDriver()
    d.team_pos = {}
    s, _ = make("CBLS", STAR, rid=0, n=4, driver=d)
    s.start(0, 0.0)
    s.on_message([2, 32, 3, 1], 1.0)       # robot 2 heads to 1
    assert s.team_size_heard() == 1 and s._taken() == set()
    d.team_pos[1] = (0.0, 0.0)             # robot 1's position heard: TEAMSIZE 2
    assert s.team_size_heard() == 2 and s._taken() == set()
    d.team_pos[3] = (0.0, 0.0)             # robot 3's: TEAMSIZE 4, robot 2 now counts
    assert s.team_size_heard() == 4 and s._taken() == {1}
    d.team_pos.clear()                     # never lowered
    assert s.team_size_heard() == 4
    # robot 3 knows robots 0..3 from the start
    s3, _ = make("CBLS", STAR, rid=3, n=4, driver=FakeDriver())
    s3.driver.team_pos = {}
    s3.start(0, 0.0)
    s3.on_message([2, 32, 3, 1], 1.0)
    assert s3._taken() == {1}


def test_random_choices_are_seeded():
    a = [make("RAND", STAR, seed=3)[0] for _ in range(2)]
    seqs = []
    for s in a:
        s.start(0, 0.0)
        seqs.append([s.next_vertex(0.0)] + [s.choose_next(0.0) for _ in range(20)])
    assert seqs[0] == seqs[1] and len(set(seqs[0])) > 1


def test_dta_estimates_stay_per_agent():
    """Two DTAG agents fed the same message object decode it independently."""
    g = fc.simulator("CR", 0).g
    a, _ = make("DTAG", g, rid=0, n=3, mapname="grid")
    b, _ = make("DTAG", g, rid=1, n=3, mapname="grid")
    a.start(0, 0.0)
    b.start(24, 0.0)
    msg = [2, 40] + [5] * g.n + [12]
    a.on_message(msg, 1.0)
    b.on_message(msg, 1.0)
    a.gi.values[3] = 77.0
    assert b.gi.values[3] == pytest.approx(0.5) and np.all(a.gi.values[:3] == 0.5)


def test_msp_follows_its_file_from_the_second_entry_without_realigning():
    """grid_4_2 begins at vertex 15 while robot 2 starts on 20: the original still heads
    for the file's second entry, then the next ones, wrapping to the second."""
    from patrolling_sim.common import paths
    from patrolling_sim.planning.msp_routes import load_route
    g = fc.simulator("CR", 0).g
    route = load_route(paths.msp_route_file("grid", 4, 2), g)
    s, _ = make("MSP", g, rid=2, n=4, mapname="grid")
    s.start(20, 0.0)
    goals = [s.next_vertex(0.0)] + [s.choose_next(0.0) for _ in range(2 * len(route))]
    assert route[0] != 20 and goals[:len(route) - 1] == route[1:]
    assert goals[len(route) - 1:2 * len(route) - 2] == route[1:]


def test_msp_bal_is_its_own_algorithm_on_computed_regions():
    g = fc.simulator("CR", 0).g
    starts = [0, 13, 20, 11]
    covered = set()
    for r, v in enumerate(starts):
        s, _ = make("MSP_BAL", g, rid=r, n=4, mapname="grid")
        s.ctx.params["start_vertices"] = starts
        s.start(v, 0.0)
        assert s.route_source == "computed" and s.route[0] == s.route[-1]
        covered |= set(s.route)
    assert covered == set(range(g.n))


def test_dtap_keeps_its_bids_after_visits():
    """The original never forgets a recorded bid (a visit does not reset it) and waits
    min(timeout, 1 + 0.1 |tasks|) s per auction round."""
    s, d = make("DTAP", STAR, n=2, driver=WaitingDriver())
    s.start(0, 0.0)
    s.next_vertex(0.0)
    d.advance(1.0)
    first = s.next
    assert s.best_bid[first][1] == 0 and s.tasks == [first]
    s.send_results(1.0)
    s.on_arrival(first, 2.0)
    assert s.best_bid[first][1] == 0 and first in s.tasks      # kept after the visit
    assert d.timers and d.timers[0][0] == pytest.approx(1.0 + 1.0 + 0.1 * 1)
