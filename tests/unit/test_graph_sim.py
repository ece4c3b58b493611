"""Graph-level simulator: files, determinism, stopping rules, message delay and loss."""
import os
import subprocess
import sys

import pytest

from patrolling_sim.algorithms import names
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.monitor.results import claim_prefix
from patrolling_sim.monitor.results import parse_info_line

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def run(tmp_path, **kw):
    cfg = GraphSimConfig(results_dir=str(tmp_path), **kw)
    sim = GraphSimulator(cfg)
    stats = sim.run()
    return sim, stats


def rows(prefix):
    with open(prefix + "_idleness.csv") as f:
        lines = f.read().splitlines()
    assert lines[0] == "Time;Robot;Node;Idleness;Interferences"
    return [l.split(";") for l in lines[1:]]


def test_files_and_metrics_agree(tmp_path):
    sim, s = run(tmp_path, map="grid", robots=2, alg="CR", duration=1000, seed=1)
    for suf in ("idleness.csv", "timeresults.csv", "results.txt", "info.csv"):
        assert os.path.isfile(f"{sim.prefix}_{suf}"), suf
    assert "/grid_2/CR/" in sim.prefix
    info = parse_info_line(open(sim.prefix + "_info.csv").read())
    assert info["nav_module"] == "graph" and info["termination"] == "TIMEOUT"
    assert info["sim_duration"] == pytest.approx(1000.0)
    samples = [float(r[3]) for r in rows(sim.prefix)]
    assert len(samples) == s.n_samples > 100
    assert info["idl_avg"] == pytest.approx(sum(samples) / len(samples), abs=0.06)
    assert info["idl_max"] == pytest.approx(max(samples), abs=0.06)
    assert info["complete_cycles"] == s.cycles >= 3
    # grid edges are all 5.7 m: at 1 m/s a robot reports a vertex every 5.7 s
    times = sorted(float(r[0]) for r in rows(sim.prefix) if r[1] == "0")
    gaps = {round(b - a, 1) for a, b in zip(times, times[1:])}
    assert gaps <= {5.7, 11.4, 17.1, 22.8}


def test_deterministic(tmp_path):
    a, _ = run(tmp_path / "a", map="example", robots=3, alg="SEBS", duration=800, seed=4)
    b, _ = run(tmp_path / "b", map="example", robots=3, alg="SEBS", duration=800, seed=4)
    c, _ = run(tmp_path / "c", map="example", robots=3, alg="SEBS", duration=800, seed=5)
    assert rows(a.prefix) == rows(b.prefix)
    assert rows(a.prefix) != rows(c.prefix)


def test_stop_after_cycles(tmp_path):
    sim, s = run(tmp_path, map="grid", robots=4, alg="CGG", duration=0, cycles=3)
    assert s.cycles == 3 and sim.termination == "CYCLES"
    assert parse_info_line(open(sim.prefix + "_info.csv").read())["termination"] == "CYCLES"
    blocks = open(sim.prefix + "_results.txt").read().count("Complete Patrol Cycles:")
    assert blocks == 3


def test_cgg_beats_random_on_worst_idleness(tmp_path):
    _, cgg = run(tmp_path, map="grid", robots=4, alg="CGG", duration=3000)
    _, rnd = run(tmp_path, map="grid", robots=4, alg="RAND", duration=3000)
    assert cgg.global_max < rnd.global_max / 2


def test_loss_and_delay(tmp_path):
    sim, _ = run(tmp_path, map="grid", robots=3, alg="GBS", duration=600, loss=0.5, seed=2)
    assert sim.messages_sent > 100
    assert 0.35 < sim.messages_lost / sim.messages_sent < 0.65
    sim0, _ = run(tmp_path, map="grid", robots=3, alg="GBS", duration=600, loss=0.0, seed=2)
    assert sim0.messages_lost == 0


def test_goal_wait_slows_visits(tmp_path):
    _, fast = run(tmp_path, map="grid", robots=1, alg="CR", duration=1000)
    _, slow = run(tmp_path, map="grid", robots=1, alg="CR", duration=1000, gwait=5.7)
    # reports = counted visits + the 25 uncounted first visits
    assert slow.total_visits + 25 == pytest.approx((fast.total_visits + 25) / 2, rel=0.03)


def test_go_time_is_how_long_the_agents_clock_ran_before_go(tmp_path):
    """As in ROS mode, where the agents' clock starts with the simulator: a vertex a robot
    has not visited has the idleness of the clock, counted from ``go_time`` s before GO."""
    figures = {}
    for go in (0.0, 7.0):
        sim = GraphSimulator(GraphSimConfig(results_dir=str(tmp_path), map="grid", robots=1,
                                            alg="CR", duration=20.0, go_time=go))
        stats = sim.run(write=False)
        strat = sim.robots[0].core.strategy
        assert strat.clock_zero == -go
        unseen = [v for v in range(sim.g.n) if strat.last_visit[v] == -go]
        assert unseen
        assert all(strat.idleness[v] >= go + 10.0 for v in unseen)   # refreshed after 10 s
        figures[go] = (stats.total_visits, len(unseen))
    assert figures[0.0] == figures[7.0]      # CR's argmax does not move with the offset


def test_without_positions_cbls_heeds_only_lower_ids(tmp_path):
    """``positions`` off, as in the abstract world (no move_base feedback): no agent hears a
    teammate's position, so CBLS's local team size stays its own id + 1 (robot 0 heeds no
    intention, robot 3 those of robots 0-2); with positions heard it is the whole team."""
    sizes = {}
    for heard in (True, False):
        sim = GraphSimulator(GraphSimConfig(results_dir=str(tmp_path), map="grid", robots=4,
                                            alg="CBLS", duration=60.0, interference=False,
                                            positions=heard))
        sim.run(write=False)
        assert all(bool(r.core.team_pos) == heard for r in sim.robots)
        sizes[heard] = [r.core.strategy.team_size_heard() for r in sim.robots]
    assert sizes == {True: [4, 4, 4, 4], False: [1, 2, 3, 4]}


@pytest.mark.parametrize("kw,needle", [
    (dict(alg="NOPE"), "argument --alg: unknown algorithm 'NOPE'"),
    (dict(robots=0), "argument --robots"),
    (dict(duration=0), "argument --duration"),
    (dict(loss=1.0), "argument --loss"),
    (dict(go_time=-1.0), "argument --go-time"),
    (dict(go_time=float("inf")), "argument --go-time"),
    (dict(map="atlantis"), "atlantis"),
    (dict(positions=False), "argument --positions: off needs --interference off"),
])
def test_bad_config(kw, needle, tmp_path):
    with pytest.raises(PatrolInputError) as e:
        GraphSimConfig(results_dir=str(tmp_path), **kw).validate()
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_claim_prefix_unique(tmp_path):
    p = str(tmp_path / "x" / "20260101_000000")
    assert claim_prefix(p) == p
    assert claim_prefix(p) == p + "_1"


def test_cli(tmp_path):
    out = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_sim.py"),
                          "--map", "1r5", "--robots", "2", "--alg", "MSP", "--duration", "300",
                          "--results-dir", str(tmp_path), "--repeat", "2", "--quiet"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("results: ") == 2
    bad = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_sim.py"),
                          "--robots", "x"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    bad = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_sim.py"),
                          "--alg", "XX", "--results-dir", str(tmp_path)],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "unknown algorithm 'XX'" in bad.stderr


@pytest.mark.parametrize("alg", names())
@pytest.mark.parametrize("mapname,n", [("1r5", 3), ("1r5", 8), ("cumberland", 8)])
def test_every_algorithm_runs_crowded_teams(alg, mapname, n, tmp_path):
    """Many robots on few vertices, with delay and loss: time advances, every vertex is
    visited, the run ends (a zero-time decision loop would hang or explode here)."""
    sim, s = run(tmp_path, map=mapname, robots=n, alg=alg, duration=600, comm_delay=0.5,
                 loss=0.1, seed=1)
    assert sim.termination == "TIMEOUT"
    assert s.n_samples > 0
    assert all(v >= 0 for v in sim.monitor.visits), f"{alg} left vertices unvisited"


# -- the graph world around the shared life cycle: interference, failure, travel ----------
from patrolling_sim.algorithms import REGISTRY  # noqa: E402
from patrolling_sim.algorithms.base import PatrolStrategy  # noqa: E402
from patrolling_sim.model.graph import PatrolGraph, parse_graph  # noqa: E402


class _Plan(PatrolStrategy):
    """Robot i visits ``params['plans'][i]`` in order, then stays on its last vertex."""
    name = "_PLAN"

    def choose_next(self, now):
        plan = self.ctx.params["plans"][self.id]
        k = self.ctx.params.setdefault("_k", {}).get(self.id, 0)
        self.ctx.params["_k"][self.id] = k + 1
        return plan[k] if k < len(plan) else plan[-1]

    def on_goal_failed(self, vertex, now):
        self.next = self.choose_next(now)
        return self.next


def plan_run(monkeypatch, starts, plans, pgraph=None, **kw):
    """Run _Plan; returns (sim, [(t, robot, message)] of everything put on /results)."""
    monkeypatch.setitem(REGISTRY, "_PLAN", _Plan)
    kw.setdefault("duration", 60)
    cfg = GraphSimConfig(robots=len(starts), alg="_PLAN", params={"plans": plans}, **kw)
    sim = GraphSimulator(cfg, start_vertices=starts, pgraph=pgraph)
    rec, publish = [], sim.publish
    sim.publish = lambda s, d: (rec.append((sim.t, s, list(d))), publish(s, d))
    sim.run(write=False)
    return sim, rec


def reports(rec, robot):
    return [(t, d[2]) for t, s, d in rec if s == robot and d[1] == 11]


def test_interference_on_an_edge(monkeypatch):
    # grid, 5.7 m edges: after a round trip each, robot 0 goes 0->1 while robot 1 goes 1->0
    starts, plans = [0, 1], {0: [5, 0, 1], 1: [2, 1, 0]}
    sim, rec = plan_run(monkeypatch, starts, plans)
    hits = [(t, s) for t, s, d in rec if d[1] == 12]
    assert [s for _, s in hits] == [1] and sim.monitor.interferences == 1
    (t_hit, _), = hits
    r0, r1 = reports(rec, 0), reports(rec, 1)
    d0, d1 = r0[0][0], r1[0][0]                      # start delays
    # head-on: the gap closes at 2 m/s from 5.7 m; the detection happens mid-edge
    assert 11.4 + max(d0, d1) < t_hit < 11.4 + min(d0, d1) + 3.7 / 2 + 0.2 + 1e-9
    # robot 1 stood still 3 s, then finished the same edge; robot 0 went on
    assert dict((v, t) for t, v in r1[3:4])[0] == pytest.approx(d1 + 17.1 + 3.0, abs=1e-6)
    assert r0[3] == (pytest.approx(d0 + 17.1, abs=1e-6), 1)
    off, rec_off = plan_run(monkeypatch, starts, plans, interference=False)
    assert off.monitor.interferences == 0
    assert reports(rec_off, 1)[3][0] == pytest.approx(d1 + 17.1, abs=1e-6)


def test_interference_at_a_vertex(monkeypatch):
    # both reach vertex 1 at about the same time, one from above, one from the side
    sim, rec = plan_run(monkeypatch, [0, 6], {0: [5, 0, 1, 2], 1: [11, 6, 1, 0]})
    hits = [t for t, s, d in rec if d[1] == 12]
    assert [s for t, s, d in rec if d[1] == 12] == [1]
    assert 11.4 < hits[0] < 17.1 + 1.0
    # detected within 2 m of each other, both close to vertex 1 (each < 2 m away from it)
    r0 = dict((v, t) for t, v in reports(rec, 0))
    assert abs(hits[0] - r0[1]) < 2.0 + 0.2


def test_unreachable_goal_fails_like_navigation(monkeypatch):
    # 0 -- 1 (10 m), 2 isolated: a goal to 2 fails, is resent 3 times, then abandoned
    text = ("3 100 100 0.1 0 0\n"
            "0 10 10 1 1 E 100\n"
            "1 110 10 1 0 W 100\n"
            "2 50 90 0\n")
    g = PatrolGraph(parse_graph(text))
    sim, rec = plan_run(monkeypatch, [0], {0: [2, 1, 0]}, pgraph=g, map="grid", duration=40)
    r = reports(rec, 0)
    d0 = r[0][0]
    assert [v for _, v in r[:3]] == [0, 1, 0]
    assert 2 not in [v for _, v in r]
    # 4 attempts, each failing at once and followed by the 1 s back-up, then 10 m at 1 m/s
    assert r[1][0] == pytest.approx(d0 + 4 * 1.0 + 10.0, abs=1e-6)


def test_goal_fail_probability(monkeypatch, tmp_path):
    from patrolling_sim.graphsim import simulator as graph_sim
    count = {"goal": 0, "backup": 0}
    send_goal = graph_sim.Robot.send_goal

    def counting_send_goal(robot, vertex, seq):
        count["goal"] += 1
        send_goal(robot, vertex, seq)
    monkeypatch.setattr(graph_sim.Robot, "send_goal", counting_send_goal)
    monkeypatch.setattr(graph_sim.Robot, "backup",
                        lambda robot: count.__setitem__("backup", count["backup"] + 1))
    kw = dict(map="grid", robots=2, alg="CR", duration=600, seed=3, interference=False)
    ok = GraphSimulator(GraphSimConfig(**kw)).run(write=False)
    assert count["backup"] == 0
    bad = GraphSimulator(GraphSimConfig(goal_fail=0.3, **kw)).run(write=False)
    assert bad.total_visits < ok.total_visits
    count.update(goal=0, backup=0)
    again = GraphSimulator(GraphSimConfig(goal_fail=0.3, **kw)).run(write=False)
    assert 0.2 < count["backup"] / count["goal"] < 0.4       # each goal fails with p = 0.3
    assert (bad.total_visits, bad.global_avg) == (again.total_visits, again.global_avg)
    with pytest.raises(PatrolInputError, match="--goal-fail"):
        GraphSimConfig(goal_fail=1.0, **kw).validate()
    with pytest.raises(PatrolInputError, match="--travel"):
        GraphSimConfig(travel="teleport", **kw).validate()


def test_euclidean_travel_is_a_straight_line(monkeypatch):
    # grid 0 -> 6 is diagonal: 2 edges (11.4 m) along the graph, 8.06 m in a straight line
    for travel, metres in (("graph", 11.4), ("euclidean", (2 * 5.7 ** 2) ** 0.5)):
        sim, rec = plan_run(monkeypatch, [0], {0: [6, 0]}, travel=travel, duration=30)
        r = reports(rec, 0)
        assert r[1][1] == 6 and r[1][0] - r[0][0] == pytest.approx(metres, abs=1e-6)


def test_deterministic_with_interference_and_failures(tmp_path):
    kw = dict(map="cumberland", robots=6, alg="SEBS", duration=900, seed=2, goal_fail=0.05,
              comm_delay=0.3, loss=0.1)
    a, sa = run(tmp_path / "a", **kw)
    b, sb = run(tmp_path / "b", **kw)
    assert sa.interferences > 0
    assert rows(a.prefix) == rows(b.prefix)


@pytest.mark.parametrize("mapname,n,alg,seed", [
    ("1r5", 5, "GBS", 1), ("cumberland", 6, "CR", 1),
    # edges whose cost is below their straight length: robots move faster than `speed` in
    # the plane (graph.max_stretch 2.25); a bound at `speed` found this interference late
    ("move_base_arena", 12, "RAND", 0),
    ("DIAG_labs", 12, "DTAP", 1),
    # an arrival at exactly a tick's time (t = 1029.0 s): the tick must come after it
    # whenever the tick was scheduled (a tick scheduled ahead came first: a false interference)
    ("DIAG_labs", 4, "GBS", 2)])
def test_skipped_feedback_work_changes_nothing(monkeypatch, mapname, n, alg, seed):
    """The simulator skips feedback ticks and interference checks that cannot find
    anything; simulating every tick and asking every core gives the same messages."""
    out = []
    for lazy in (True, False):
        cfg = GraphSimConfig(map=mapname, robots=n, alg=alg, seed=seed,
                             duration={"move_base_arena": 2100, "DIAG_labs": 1100}.get(
                                 mapname, 900))
        sim = GraphSimulator(cfg)
        sim.skip_idle_ticks = lazy
        rec, publish = [], sim.publish
        sim.publish = lambda s, d, rec=rec, sim=sim, publish=publish: (
            rec.append((sim.t, s, list(d))), publish(s, d))
        sim.run(write=False)
        out.append(rec)
    assert sum(1 for _, _, d in out[0] if d[1] == 12) > 0
    assert out[0] == out[1]


def test_first_tick_at_is_the_first_lattice_point_not_before_t():
    from patrolling_sim.graphsim.feedback import first_tick_at
    from patrolling_sim.graphsim.config import FEEDBACK_PERIOD as P
    for t in (0.0, 0.1, 0.2, 1029.0, 1029.0000001, 5145 * P, 5145 * P + 1e-12, 7.3, 3599.9):
        k = first_tick_at(t)
        assert k * P >= t and (k == 0 or (k - 1) * P < t), (t, k)


@pytest.mark.parametrize("kw", [
    dict(map="grid", robots=4, alg="CR", seed=1),                     # multi-edge trips
    dict(map="cumberland", robots=6, alg="DTAG", seed=2),              # interference stops
    dict(map="grid", robots=3, alg="RAND", seed=5, travel="euclidean", goal_fail=0.3),
])
def test_xy_at_is_position_without_the_location(kw):
    """The feedback tick's xy_at repeats position()'s arithmetic inline: it must give the
    same floats, to the last bit, at every instant of every trip (a different rounding
    would change which robots are found near each other)."""
    sim = GraphSimulator(GraphSimConfig(duration=300, **kw))
    checked = []
    publish = sim.publish

    def check(sender, data):
        for r in sim.robots:
            if r.pieces is None:
                continue
            for frac in (0.0, 0.137, 0.5, 0.999, 1.0, 1.7):
                t = r.depart + frac * r.duration
                x, y, _ = r.position(t)
                assert r.xy_at(t) == (x, y)
                checked.append(t)
        publish(sender, data)
    sim.publish = check
    sim.run(write=False)
    assert len(checked) > 100
