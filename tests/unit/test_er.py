"""ER, Expected Reactive (docs/algorithms/ER.md): the rule on a hand-made graph (a
neighbour a teammate reaches first is avoided), its messages and their time codes, and
graph-mode runs under --attrition and --comm."""
import pytest

from patrolling_sim.algorithms.msgtime import HORIZON, decode_time, encode_time
from patrolling_sim.algorithms.testing import deliver, make_strategy, walk
from patrolling_sim.common.protocol import MSG_ER_INTENTION, MSG_ER_VISIT
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.algorithms.testing import graph_from as hand_made_graph


def graph_from(vertices, edges):
    """A hand-made graph on a 400 px map (:func:`~patrolling_sim.algorithms.testing.graph_from`)."""
    return hand_made_graph(vertices, edges, size_px=400)


#: vertex 0 between 1 and 2, both 10 m away (10 s at 1 m/s); 3 hangs off 1 and 2
FORK = graph_from({0: (200, 200), 1: (100, 200), 2: (300, 200), 3: (200, 300)},
                  {(0, 1): 100, (0, 2): 100, (1, 3): 141, (2, 3): 141})


def er(rid=0, n=2, seed=0, params=None):
    return make_strategy("ER", graph=FORK, robot_id=rid, team_size=n, seed=seed,
                         params=params)


def at_zero(seed, now=100.0):
    s, d = er(seed=seed)
    s.start(0, 0.0)
    s.on_arrival(0, now)
    return s, d


def test_alone_both_neighbours_tie():
    firsts = {at_zero(seed)[0].next_vertex(100.0) for seed in range(30)}
    assert firsts == {1, 2}


@pytest.mark.parametrize("eta", [105.0, 112.0])
def test_avoids_a_neighbour_a_teammate_reaches_around_its_own_arrival(eta):
    """Robot 0 on vertex 0 at t=100 would reach 1 or 2 at t=110. Teammate 1 announced it is
    heading to 1, due at ``eta``: before (105) or just after (112) that arrival, vertex 1's
    expected idleness is the gap (5 s, 2 s), vertex 2's the full 110 s: robot 0 takes 2,
    whatever the seed."""
    for seed in range(20):
        s, _ = at_zero(seed)
        s.on_message((1, MSG_ER_VISIT, 3, 1, encode_time(eta)), 100.0)
        assert s.expected_idleness(1, 110.0, 100.0) == pytest.approx(abs(110.0 - eta))
        assert s.expected_idleness(2, 110.0, 100.0) == pytest.approx(110.0)
        assert s.next_vertex(100.0) == 2


def test_an_expired_announcement_no_longer_counts():
    firsts = set()
    for seed in range(30):
        s, _ = at_zero(seed)
        s.on_message((1, MSG_ER_INTENTION, 1, encode_time(95.0)), 90.0)   # due at 95
        firsts.add(s.next_vertex(100.0))
    assert firsts == {1, 2}


def test_two_robots_split_through_their_messages():
    """Both robots stand on vertex 0; robot 0 decides and broadcasts first, robot 1 hears
    it and takes the other branch."""
    for seed in range(20):
        a, da = er(rid=0, seed=seed)
        b, _ = er(rid=1, seed=seed)
        a.start(0, 0.0)
        b.start(0, 0.0)
        va = a.next_vertex(0.2)
        a.send_results(0.2)
        assert da.sent == [[0, MSG_ER_VISIT, 0, va, encode_time(10.2)]]
        deliver(da.sent, [b], 0.3)
        assert b.intention == {0: (va, 10.2)}
        assert b.next_vertex(0.5) == 3 - va


def test_a_received_visit_is_a_visit_at_its_arrival():
    s, _ = at_zero(0)
    s.on_message((1, MSG_ER_VISIT, 2, 3, encode_time(120.0)), 100.0)
    assert s.last_visit[2] == 100.0
    assert s.next_vertex(100.0) == 1                # 2 was just visited


def test_goal_failure_and_repair_announce_the_new_goal():
    s, d = at_zero(0)
    s.next_vertex(100.0)
    v = s.on_goal_failed(s.next, 130.0)
    assert d.sent[-1] == [0, MSG_ER_INTENTION, v, encode_time(s.eta)]
    d.sent.clear()
    s.on_repair(400.0)
    v = s.next_vertex(400.0)
    assert d.sent == [[0, MSG_ER_INTENTION, v, encode_time(410.0)]]
    s.next_vertex(410.0)
    assert len(d.sent) == 1                          # once only


def test_silent_teammate_is_forgotten():
    s, _ = at_zero(0)
    s.on_message((1, MSG_ER_INTENTION, 1, encode_time(500.0)), 100.0)
    s.on_teammate_silent(1, 220.0)
    assert s.intention == {}


def test_time_codes_fit_int16_and_round_trip_beyond_the_int16_range():
    for t in (0.0, 10.2, 3276.7, 3276.8, 5000.05, 40000.0):
        code = encode_time(t)
        assert 0 <= code <= 32767
        for lag in (-30.0, 0.0, 2.5, HORIZON - 1.0):
            assert decode_time(code, t + lag) == pytest.approx(t, abs=0.0501)   # to the tick
    # a long slow walk: every message the strategy sends fits (RecordingDriver checks)
    s, d = make_strategy("ER", "cumberland", seed=1)
    walk(s, d, 0, 300, speed=0.2)
    assert d.t > 3276.8 and len(d.sent) == 301


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="speed and edge_min"):
        er(params={"speed": 0})


# ----------------------------------------------------------------------- graph mode
def run(tmp_path, **kw):
    kw.setdefault("map", "grid")
    sim = GraphSimulator(GraphSimConfig(results_dir=str(tmp_path), alg="ER", **kw))
    sim.run()
    return sim


def visited_after(sim, t0):
    from patrolling_sim.monitor.metrics import read_visits
    return {v for t, _, v in read_visits(sim.prefix + "_visits.csv") if t > t0}


def test_graph_mode_attrition_survivors_forget_the_failed_robot(tmp_path):
    sim = run(tmp_path, robots=4, duration=1800, seed=3, attrition="2@600")
    assert sim.termination == "TIMEOUT" and sim.monitor.failures == [[2, 600.0, None]]
    assert visited_after(sim, 600.0) == set(range(sim.g.n))
    for r in (0, 1, 3):
        assert 2 not in sim.robots[r].core.strategy.intention
        assert set(sim.robots[r].core.strategy.intention) == {0, 1, 3} - {r}


@pytest.mark.parametrize("comm", ["bernoulli:p=0.3;delay=const:0.5", "range:r=0.001,los=false"])
def test_graph_mode_comm_models_carry_the_announcements(tmp_path, comm):
    """The announcements go through the model: with loss and delay the robots still hear
    each other (and decode the times exactly); with no link at all nobody knows anything of
    the others, and every vertex is still patrolled."""
    from patrolling_sim.scenarios.scenario import read_scenario
    sim = run(tmp_path, robots=4, duration=900, seed=1, comm=comm)
    assert sim.termination == "TIMEOUT" and visited_after(sim, 300.0) == set(range(sim.g.n))
    c = read_scenario(sim.prefix)["counters"]["total"]
    assert c["results_sent"] > 200 and c["results_lost"] > 0
    heard = [sim.robots[r].core.strategy.intention for r in range(4)]
    if comm.startswith("range"):
        assert heard == [{}] * 4 and c["results_delivered"] == 0
    else:
        assert all(len(h) == 3 for h in heard)
        for h in heard:      # etas restored near the clock: within a trip of the end
            assert all(abs(eta - 900.0) < 60.0 for _, eta in h.values())
