"""Scenarios (docs/scenarios.md): robot failures and communication models in graph mode,
the monitor's failure records, the scenario file and the failure-impact columns."""
import math
import os

import pytest

from patrolling_sim.algorithms import REGISTRY
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.graphsim.cli import main
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.monitor.metrics import read_visits
from patrolling_sim.monitor.core import MonitorCore
from patrolling_sim.monitor.run_status import read_run_yaml
from patrolling_sim.scenarios.scenario import check_scenario, read_scenario, scenario_columns


def run(tmp_path, **kw):
    kw.setdefault("map", "grid")
    sim = GraphSimulator(GraphSimConfig(results_dir=str(tmp_path), **kw))
    stats = sim.run()
    return sim, stats


def visits(sim):
    return read_visits(sim.prefix + "_visits.csv")


#: the auction algorithms (DTAP's machinery): their silence hook forgets a failed robot's bids
AUCTIONS = ("DTAP", "DTASSI")


# ------------------------------------------------------------------------------ monitor
def test_monitor_records_failures_and_exempts_them_from_the_silence_rule():
    m = MonitorCore(4, 3)
    m.start(100.0)
    m.visit(0, 1, 110.0)
    m.robot_failed(2, 150.0)
    m.robot_failed(2, 160.0)                      # already down: ignored
    assert m.dead_robots == {2} and m.failures == [[2, 50.0, None]]
    # robot 1 silent since GO, robot 2 failed: only robot 1 is a FAIL candidate
    assert m.silent_robots(400.0, 200.0) == [0, 1]
    assert m.silent_robots(230.0, 125.0) == [1]
    m.robot_repaired(2, 400.0)
    assert m.dead_robots == set() and m.failures == [[2, 50.0, 300.0]]
    assert m.silent_robots(450.0, 100.0) == [0, 1]    # 2's clock restarted at its repair


# ------------------------------------------------------------------------------ attrition
def test_failure_applied_at_its_time_robot_stops_and_run_is_not_fail(tmp_path):
    sim, _ = run(tmp_path, robots=4, alg="SEBS", duration=1800, seed=3, attrition="2@600")
    assert sim.termination == "TIMEOUT"
    assert read_run_yaml(sim.prefix)["status"] == "TIMEOUT"
    assert sim.monitor.failures == [[2, 600.0, None]]
    v = visits(sim)
    mine = [t for t, r, _ in v if r == 2]
    assert mine and max(mine) <= 600.0 and min(mine) < 600.0
    for r in (0, 1, 3):                             # the others keep patrolling to the end
        assert max(t for t, rr, _ in v if rr == r) > 1700.0
    assert {x for t, _, x in v if t > 600.0} == set(range(sim.g.n))
    # each robot's longest silence in _run.yaml, from the visit log: robot 2's ends at its
    # failure (its down time is not silence), the others' at the end of the run
    for r in range(4):
        times = [0.0] + [t for t, rr, _ in v if rr == r] + [600.0 if r == 2 else 1800.0]
        gap = max(b - a for a, b in zip(times, times[1:]))
        assert read_run_yaml(sim.prefix)["longest_silence"][r] == pytest.approx(gap, abs=0.06)
    body = sim.robots[2]
    assert body.pieces is None and body.core.failed           # stands where it stopped
    assert sim.team_pos[2] == body.xy
    # silent-teammate hook: nobody keeps robot 2's intention
    for r in (0, 1, 3):
        assert 2 not in sim.robots[r].core.strategy.intention
    doc = read_scenario(sim.prefix)
    assert doc["schedule"] == "2@600" and doc["failures"] == [
        {"robot": 2, "t_fail": 600.0, "t_repair": None}]


def test_repair_brings_the_robot_back(tmp_path):
    sim, _ = run(tmp_path, robots=3, alg="CR", duration=1500, seed=1, attrition="1@500+300")
    assert sim.monitor.failures == [[1, 500.0, 800.0]]
    ts = [t for t, r, _ in visits(sim) if r == 1]
    assert not [t for t in ts if 500.0 < t < 800.0]
    assert [t for t in ts if t > 850.0]


@pytest.mark.parametrize("alg", ["SEBS", "DTAP", "DTASSI"])
def test_history_before_the_failure_is_unchanged(tmp_path, alg):
    """Until the failure, a run with a scheduled failure is the run without one."""
    a, _ = run(tmp_path / "a", robots=4, alg=alg, duration=900, seed=2)
    b, _ = run(tmp_path / "b", robots=4, alg=alg, duration=900, seed=2, attrition="1@700")
    assert [x for x in visits(a) if x[0] < 700.0] == [x for x in visits(b) if x[0] < 700.0]
    assert not os.path.exists(a.prefix + "_scenario.yaml")
    assert os.path.exists(b.prefix + "_scenario.yaml")


def _after(sim, att, seed, alg, tmp_path):
    return run(tmp_path, robots=6, alg=alg, duration=3600, seed=seed, attrition=att)[0]


@pytest.mark.parametrize("alg", ["SEBS", "CBLS", "CR", "DTAP", "DTASSI", "MSP"])
def test_grid_six_robots_two_failures_at_1200(tmp_path, alg):
    """Acceptance: grid, 6 robots, 3600 s, robots 2 and 4 fail at 1200 s."""
    sim = _after(sim=None, att="2@1200,4@1200", seed=0, alg=alg, tmp_path=tmp_path)
    assert sim.termination == "TIMEOUT"
    assert sorted(f[:2] for f in sim.monitor.failures) == [[2, 1200.0], [4, 1200.0]]
    cols = scenario_columns(sim.prefix)
    assert cols["failures"] == 2 and cols["first_failure"] == 1200.0
    after_visited = {x for t, _, x in visits(sim) if t > 1200.0}
    if alg.startswith("MSP"):
        # MSP keeps its rule: the failed robots' routes that nobody else covers are orphaned
        routes = {r.id: set(r.core.strategy.route) for r in sim.robots}
        alive = set().union(*(routes[r] for r in (0, 1, 3, 5)))
        orphaned = (routes[2] | routes[4]) - alive
        assert orphaned and after_visited == set(range(sim.g.n)) - orphaned
        assert cols["idl_after"] > 3 * cols["idl_before"]
        return
    assert after_visited == set(range(sim.g.n))
    if alg in AUCTIONS:
        # DTAP's idleness still falls after 1200 s without failure (its task sets are still
        # converging), so compare with the same seed's run without failure
        base = run(tmp_path / "base", robots=6, alg=alg, duration=3600, seed=0)[0]
        from patrolling_sim.monitor.metrics import failure_impact, graph_idleness_series
        t, s = graph_idleness_series(visits(base), base.g.n, 3600.0)
        assert cols["idl_after"] > failure_impact(t, s, 1200.0, 3600.0).after
        # its silence hook: no survivor keeps a bid won by a failed robot
        for r in (0, 1, 3, 5):
            owners = {o for _, o in sim.robots[r].core.strategy.best_bid.values()}
            assert not owners & {2, 4}
    else:
        assert cols["idl_after"] > cols["idl_before"]


@pytest.mark.parametrize("alg", sorted(REGISTRY))
def test_every_algorithm_keeps_running_after_one_failure(tmp_path, alg):
    """Acceptance: grid, 6 robots, 3600 s, robot 2 fails at 1200 s, every algorithm: the
    run ends with TIMEOUT, the failure is recorded at 1200 s, every vertex is still visited
    (apart from the MSP routes nobody else covers) and the settled idleness is higher
    (DTAP: higher than without the failure, docs/scenarios.md)."""
    sim = run(tmp_path, robots=6, alg=alg, duration=3600, seed=0, attrition="2@1200")[0]
    assert sim.termination == "TIMEOUT" and sim.monitor.failures == [[2, 1200.0, None]]
    cols = scenario_columns(sim.prefix)
    after_visited = {x for t, _, x in visits(sim) if t > 1200.0}
    if alg.startswith("MSP"):
        # the failed robot's route that nobody else covers is orphaned; the rest is visited
        routes = {r.id: set(r.core.strategy.route) for r in sim.robots}
        alive = set().union(*(routes[r] for r in routes if r != 2))
        assert after_visited == set(range(sim.g.n)) - (routes[2] - alive) < set(range(sim.g.n))
    else:
        assert after_visited == set(range(sim.g.n))
    if alg != "DTAP":
        assert cols["idl_after"] > cols["idl_before"]
    else:
        # still converging at 1200 s: compare with the same seed's run without failure
        base = run(tmp_path / "base", robots=6, alg=alg, duration=3600, seed=0)[0]
        from patrolling_sim.monitor.metrics import failure_impact, graph_idleness_series
        t, s = graph_idleness_series(visits(base), base.g.n, 3600.0)
        assert cols["idl_after"] > failure_impact(t, s, 1200.0, 3600.0).after


def test_bad_scenarios_are_one_line_errors(tmp_path, capsys):
    with pytest.raises(PatrolInputError, match="--attrition: robot 7 is not in a team of 3"):
        check_scenario("perfect", "7@100", 3)
    with pytest.raises(PatrolInputError, match="not before the end of the run"):
        check_scenario("perfect", "1@4000", 3, duration=3600)
    with pytest.raises(PatrolInputError, match="--comm: unknown communication model"):
        check_scenario("wifi", "none", 3)
    rc = main(["--map", "grid", "--robots", "2", "--duration", "60", "--results-dir",
               str(tmp_path), "--comm", "bernoulli:p=2"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and "--comm: bernoulli: p must be in [0, 1]" in err
    assert not os.listdir(tmp_path)
    rc = main(["--map", "grid", "--robots", "2", "--duration", "60", "--results-dir",
               str(tmp_path), "--attrition", "0@10,1@20"])
    assert rc == 2 and "every robot of the team" in capsys.readouterr().err


# ------------------------------------------------------------------------------ comm
def _share(sim, kind="results"):
    c = read_scenario(sim.prefix)["counters"]["total"]
    assert c["sent"] == c["delivered"] + c["lost"]
    return c[kind + "_delivered"] / c[kind + "_sent"], c


@pytest.mark.parametrize("comm,lo,hi", [
    ("bernoulli:p=0.3", 0.67, 0.73),
    ("ge:p_good=0,p_bad=1,to_bad=0.1,to_good=0.1", 0.45, 0.55),     # bad half of the time
    ("range:r=0.001,los=false", 0.0, 0.0),
    ("perfect;delay=const:0.5", 1.0, 1.0),
])
def test_delivered_share_follows_the_model(tmp_path, comm, lo, hi):
    sim, _ = run(tmp_path, robots=4, alg="SEBS", duration=900, seed=1, comm=comm)
    share, c = _share(sim, "positions")
    assert c["positions_sent"] > 5000
    assert lo <= share <= hi
    rshare, _ = _share(sim, "results")
    assert c["results_sent"] > 300
    assert lo - 0.08 <= rshare <= hi + 0.08


@pytest.mark.parametrize("alg", AUCTIONS)
def test_auctions_under_loss_delay_failure_and_repair(tmp_path, alg):
    """grid, 3 robots, 300 s; a fifth of the messages lost, the rest delayed; robot 1 down from
    80 s to 180 s. The auctions end on their timers whatever is lost: the run ends with
    TIMEOUT, robot 1 is silent while down and patrols again after its repair, the others
    keep visiting, and the same seed gives the same run."""
    kw = dict(robots=3, alg=alg, duration=300, seed=4, attrition="1@80+100",
              comm="bernoulli:p=0.2;delay=exp:0.3")
    sim, _ = run(tmp_path / "a", **kw)
    twin, _ = run(tmp_path / "b", **kw)
    assert sim.termination == "TIMEOUT" and visits(sim) == visits(twin)
    assert sim.monitor.failures == [[1, 80.0, 180.0]]
    v = visits(sim)
    mine = [t for t, r, _ in v if r == 1]
    assert not [t for t in mine if 80.0 < t < 180.0]
    assert len([t for t in mine if t > 180.0]) >= 3
    assert len({x for t, r, x in v if r != 1 and 80.0 < t < 180.0}) >= 5
    share, c = _share(sim, "results")
    assert c["results_sent"] > 100 and 0.7 <= share <= 0.9


def test_comm_model_is_seeded_and_changes_the_run(tmp_path):
    a, sa = run(tmp_path / "a", robots=4, alg="SEBS", duration=600, seed=5,
                comm="bernoulli:p=0.5;delay=exp:0.3")
    b, sb = run(tmp_path / "b", robots=4, alg="SEBS", duration=600, seed=5,
                comm="bernoulli:p=0.5;delay=exp:0.3")
    p, _ = run(tmp_path / "p", robots=4, alg="SEBS", duration=600, seed=5)
    assert visits(a) == visits(b)
    assert read_scenario(a.prefix)["counters"] == read_scenario(b.prefix)["counters"]
    assert visits(a) != visits(p)


def test_line_of_sight_drops_more_than_range_alone(tmp_path):
    """cumberland has walls: with line of sight fewer messages arrive than by range alone."""
    los, _ = run(tmp_path / "los", map="cumberland", robots=4, alg="CR", duration=400,
                 seed=1, comm="range:r=15,los=true")
    rng, _ = run(tmp_path / "rng", map="cumberland", robots=4, alg="CR", duration=400,
                 seed=1, comm="range:r=15,los=false")
    s_los, _ = _share(los, "positions")
    s_rng, _ = _share(rng, "positions")
    assert 0.0 < s_los < s_rng < 1.0
    assert not math.isnan(s_los)


# ------------------------------------------------------------------------------ report
def test_report_has_a_scenarios_section_with_the_failure_marked(tmp_path):
    from patrolling_sim.report.build import build_report
    res = tmp_path / "results"
    for alg in ("CR", "SEBS"):
        for seed in (0, 1):
            run(res, robots=3, alg=alg, duration=600, seed=seed, attrition="1@300")
    run(res, robots=3, alg="CR", duration=600, seed=0)            # no scenario file
    out = build_report([str(res)], str(tmp_path / "report"), run_plots=False)
    html = open(os.path.join(str(tmp_path / "report"), "report.html")).read()
    assert "<h2>Scenarios</h2>" in html or ">Scenarios<" in html
    figs = [f for f in out["files"] if os.path.basename(f).startswith("scenario_")]
    assert len(figs) == 1 and os.path.getsize(figs[0]) > 1000
    assert html.count("1@300") >= 4                                # one row per run
    assert ">settled<" in html                                     # the summary table


@pytest.mark.parametrize("alg", ["DTAP", "DTASSI", "SEBS", "CBLS"])
def test_repair_resumes_even_when_the_failure_hits_mid_auction(tmp_path, alg):
    """A failure voids the robot's timers (DTAP's auction deadline among them): after the
    repair every robot must patrol again, whatever it was doing when it failed."""
    times = [80.0 + 0.37 * k for k in range(8)]
    for t in times:
        spec = f"1@{t:g}+100"
        sim, _ = run(tmp_path / f"{t:g}", robots=3, alg=alg, duration=400, seed=1,
                     attrition=spec)
        assert [x for x in visits(sim) if x[1] == 1 and x[0] > t + 110.0], spec


def test_cli_runs_a_scenario_and_records_it(tmp_path, capsys):
    rc = main(["--map", "grid", "--robots", "4", "--alg", "SEBS", "--duration", "600",
               "--seed", "3", "--results-dir", str(tmp_path), "--quiet",
               "--comm", "ge:p_bad=0.9;delay=uniform:0.1,0.4",
               "--attrition", "random:rate=3,min_team=2"])
    assert rc == 0
    prefix = capsys.readouterr().out.strip().splitlines()[-1].split()[-1].rstrip("*")
    doc = read_scenario(prefix.rstrip("_"))
    assert doc["comm"] == "ge:p_good=0,p_bad=0.9,to_bad=0.05,to_good=0.5;delay=uniform:0.1,0.4"
    assert doc["attrition"] == "random:rate=3,min_team=2"
    # the seeded draw: the explicit schedule, applied as drawn, never below 2 robots
    assert doc["schedule"] != "none"
    assert len([f for f in doc["failures"] if f["t_repair"] is None]) <= 2
    assert [f["t_fail"] for f in doc["failures"]] == pytest.approx([
        float(x.split("@")[1].split("+")[0]) for x in doc["schedule"].split(",")], abs=0.01)


def test_scenario_metrics_give_each_failure_its_impact(tmp_path):
    from patrolling_sim.scenarios.scenario import scenario_metrics
    sim, _ = run(tmp_path, robots=6, alg="SEBS", duration=3000, seed=0,
                 attrition="2@1000,4@1000,1@2000", comm="bernoulli:p=0.1")
    m = scenario_metrics(sim.prefix, sim.g.n, 3000.0)
    assert [(f["t_fail"], f["robots"]) for f in m["failures"]] == [(1000.0, [2, 4]),
                                                                   (2000.0, [1])]
    assert all(f["after"] > f["before"] for f in m["failures"])
    assert m["messages"]["sent"] == m["messages"]["delivered"] + m["messages"]["lost"] > 0
    cols = scenario_columns(sim.prefix)
    assert cols["idl_before"] == m["failures"][0]["before"]
    assert 0.85 < cols["delivered_share"] < 0.95


# ------------------------------------------------------------------------------ agent core
def test_core_fail_and_repair_with_a_fake_world():
    """The API the ROS glue calls: fail() reports [id,13,0] first, cancels the goal, voids
    the timers and goes deaf and mute; repair() reports [id,13,1] and decides again."""
    from test_agent_core import started
    core, world, log = started(robot_id=1)
    core.fail()
    assert log[0] == ("publish", world.t, [1, 13, 0]) and log[1][0] == "cancel"
    assert core.failed and core.state == "moving"
    del log[:]
    core.send([1, 40, 5])                                   # mute
    core.on_results([0, 40, 3])                             # deaf
    core.on_position(0, 1.0, 1.0)
    core.on_goal_result(core.seq, True)                     # stale: ignored
    world.advance(30.0)                                     # every old timer is void
    assert log == [] and core.comm_counters()["ignored_failed"] == 1
    assert 0 not in core.team_pos
    core.repair()
    assert log[0][2] == [1, 13, 1] and ("goal", world.t, 2) in log
    core.on_results([0, 40, 3])
    assert ("message", world.t, [0, 40, 3]) in log
    c = core.comm_counters()
    assert c["results_sent"] == c["results_delivered"] == 1 and c["lost"] == 0


def test_core_applies_the_model_at_the_receiver_with_its_delay():
    from patrolling_sim.agent.faults import make_comm
    from test_agent_core import started
    assert make_comm("perfect", 1) is None and make_comm(None, 1) is None
    core, world, log = started(robot_id=1, comm=make_comm("perfect;delay=const:0.5", 1))
    core.on_results([0, 40, 3])
    assert not [e for e in log if e[0] == "message"]
    world.advance(0.6)
    assert [e[1] for e in log if e[0] == "message"] == [pytest.approx(1.5)]
    lossy, world2, log2 = started(robot_id=1, comm=make_comm("bernoulli:p=1", 1))
    lossy.on_results([0, 40, 3])
    lossy.on_position(0, 2.0, 3.0)
    world2.advance(1.0)
    assert not [e for e in log2 if e[0] == "message"] and 0 not in lossy.team_pos
    assert lossy.true_pos[0] == (2.0, 3.0)                  # the range model's truth
    assert lossy.comm_counters()["lost"] == 2


def test_core_reports_a_silent_teammate_once():
    from test_agent_core import make, GO
    calls = []
    core, world, log = make(robot_id=0, plan=list(range(1, 5)) * 20, silence_check=True)
    core.strategy.teammate_timeout = 120.0
    core.strategy.ctx = type("Ctx", (), {"team_size": 3})()
    core.strategy.on_teammate_silent = lambda r, now: calls.append((r, now))
    core.ready()
    core.on_results(GO)
    for k in range(30):                                     # robot 2 talks, robot 1 never
        world.advance(10.0)
        core.on_results([2, 40, 1])
        if core.state == "moving":
            core.on_goal_result(core.seq, True)
    assert [r for r, _ in calls] == [1]
    assert 120.0 <= calls[0][1] <= 135.0
