"""Experiment runner: configuration parsing and validation, batches, launch generation,
process-tree bookkeeping. No ROS master needed."""
import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import pytest

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.runner.batch import expand_batch, load_batch
from patrolling_sim.runner.config import ExperimentConfig, from_positional, load_config_file
from patrolling_sim.runner.launchgen import generate_launch
from patrolling_sim.runner.proctree import ProcessTree

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPT = os.path.join(ROOT, "scripts", "start_experiments.py")


def base(**kw):
    d = dict(map="grid", robots=4, alg="CGG", loc="fake_localization", timeout=300.0)
    d.update(kw)
    return ExperimentConfig(**d)


def test_positional_form():
    cfg = from_positional("grid 4 default CR AMCL ros 3 0.2 xterm 1800 false 2.5".split())
    assert (cfg.map, cfg.robots, cfg.alg, cfg.loc, cfg.nav) == ("grid", 4, "CR", "AMCL", "ros")
    assert (cfg.gwait, cfg.comm_delay, cfg.timeout, cfg.speedup) == (3.0, 0.2, 1800.0, 2.5)
    cfg = from_positional("grid 4 default CR AMCL spqrel_navigation 0 0 gnome-terminal 60".split())
    assert cfg.validate(check_start_positions=False, check_writable=False).nav == "spqrel_nav_lite"


@pytest.mark.parametrize("args,needle", [
    ("grid 4 default CR".split(), "needs 10 to 12 arguments"),
    ("grid x default CR AMCL ros 3 0 xterm 60".split(), "argument ROBOTS: expected int"),
    ("grid 4 default CR AMCL ros abc 0 xterm 60".split(), "argument GWAIT: expected float"),
    ("grid 4 default CR AMCL ros 0 0 xterm 60 maybe".split(), "CUSTOM_STAGE: expected bool"),
])
def test_positional_errors(args, needle):
    with pytest.raises(PatrolInputError, match=needle):
        from_positional(args)


@pytest.mark.parametrize("kw,needle", [
    (dict(map="nosuch"), "unknown map 'nosuch'"),
    (dict(robots=0), "team size must be >= 1"),
    (dict(robots=-3), "team size must be >= 1"),
    (dict(alg="FOO"), "unknown algorithm 'FOO'"),
    (dict(loc="gps"), "argument --loc"),
    (dict(nav="teleport"), "argument --nav"),
    (dict(gwait=-1.0), "argument --gwait: must be >= 0"),
    (dict(loss=1.0), "argument --loss"),
    (dict(cycles=-1), "argument --cycles"),
    (dict(initpos="zz"), "no entry 'grid_4_zz'"),
    (dict(map="1r5", robots=4000), "cannot hold 4000 robots"),
])
def test_validation_errors(kw, needle, tmp_path):
    cfg = base(results_dir=str(tmp_path), **kw)
    with pytest.raises(PatrolInputError) as ei:
        cfg.validate()
    assert needle in str(ei.value) and "\n" not in str(ei.value)


def test_unwritable_results_dir(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(PatrolInputError, match="argument --results-dir: .* is not writable"):
        base(results_dir=str(f / "sub")).validate()


def test_config_file_round_trip(tmp_path):
    cfg = base(seed=7, gwait=3.0, results_dir=str(tmp_path))
    p = tmp_path / "c.yaml"
    cfg.save(str(p))
    assert load_config_file(str(p)) == cfg
    (tmp_path / "bad.yaml").write_text("map: grid\nrobtos: 4\n")
    with pytest.raises(PatrolInputError, match="unknown key 'robtos'"):
        load_config_file(str(tmp_path / "bad.yaml"))
    (tmp_path / "bad2.yaml").write_text("map: grid\nrobots: four\n")
    with pytest.raises(PatrolInputError, match="key 'robots': expected int"):
        load_config_file(str(tmp_path / "bad2.yaml"))


def test_batch_grid_and_list(tmp_path):
    cfgs = expand_batch({"base": {"map": "grid", "timeout": 60},
                         "grid": {"alg": ["CR", "CGG"], "robots": [2, 4], "seed": [1, 2]}})
    assert len(cfgs) == 8
    assert [(c.alg, c.robots, c.seed) for c in cfgs[:3]] == [("CR", 2, 1), ("CR", 2, 2),
                                                             ("CR", 4, 1)]
    assert all(c.map == "grid" and c.timeout == 60 for c in cfgs)
    p = tmp_path / "b.yaml"
    p.write_text("- {map: grid, robots: 2, alg: CR}\n- {map: example, robots: 3, alg: CGG}\n")
    assert [c.map for c in load_batch(str(p))] == ["grid", "example"]
    with pytest.raises(PatrolInputError, match="entry 2: unknown key 'speed'"):
        expand_batch([{"map": "grid"}, {"speed": 3}], "b.yaml")
    with pytest.raises(PatrolInputError, match="grid key 'alg' must be a non-empty list"):
        expand_batch({"grid": {"alg": "CR"}})


def test_generated_launch(tmp_path):
    cfg = base(results_dir=str(tmp_path), rviz=True).validate()
    pos = cfg.start_positions()
    xml = generate_launch(cfg, pos, str(tmp_path / "20260101_000000"))
    root = ET.fromstring(xml)
    # default: every agent in one patrol_agents process, robot_nav per robot
    hosts = [n for n in root.iter("node") if n.get("type") == "patrol_agents"]
    assert len(hosts) == 1 and hosts[0].get("args") == "grid 0-3"
    assert not [n for n in root.iter("node") if n.get("type") == "patrol_agent"]
    robots = [i for i in root.iter("include") if i.get("file").endswith("robot.launch")]
    assert len(robots) == 4
    assert all({a.get("name"): a.get("value") for a in r.iter("arg")}["combined"] == "true"
               for r in robots)
    mon = [n for n in root.iter("node") if n.get("type") == "monitor"][0]
    assert mon.get("required") == "true" and mon.get("args") == "grid CGG 4"
    params = {p.get("name"): p.get("value") for p in root.findall("param")}
    assert params["/use_sim_time"] == "true" and params["/goal_reached_wait"] == "0.0"
    init = root.find("rosparam").text
    assert init.startswith("[") and len(init.strip("[]").split(",")) == 8
    assert any(n.get("type") == "rviz" for n in root.iter("node"))
    # the original's layout: one patrol_agent node per robot, separate navigation nodes
    sep = ET.fromstring(generate_launch(base(results_dir=str(tmp_path), processes="separate")
                                        .validate(), pos, str(tmp_path / "20260101_000001")))
    agents = [n for n in sep.iter("node") if n.get("type") == "patrol_agent"]
    assert [a.get("name") for a in agents] == [f"patrol_robot{i}" for i in range(4)]
    # the agents' seeds of graph mode (agent_core.agent_seed): same draws in both modes
    assert [a.find("param[@name='seed']").get("value") for a in agents] == ["1", "2", "3", "4"]
    assert all({a.get("name"): a.get("value") for a in r.iter("arg")}["combined"] == "false"
               for r in sep.iter("include") if r.get("file").endswith("robot.launch"))
    with pytest.raises(PatrolInputError, match="argument --processes: must be one of"):
        base(processes="threads").validate()


def test_process_tree_stops_only_own_descendants():
    # a shell that starts a child in a new session (like roslaunch does for nodes)
    outsider = subprocess.Popen(["sleep", "60"])
    p = subprocess.Popen(["bash", "-c", "setsid sleep 60 & sleep 60 & wait"],
                         start_new_session=True)
    try:
        time.sleep(0.5)
        tree = ProcessTree(p.pid)
        assert len(tree.alive()) >= 3
        tree.stop(grace=1.0)
        assert tree.alive() == []
        assert outsider.poll() is None                  # not ours: untouched
    finally:
        outsider.kill()
        outsider.wait()
        p.wait(timeout=5)


def _cli(*args, **kw):
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True,
                          env=env, timeout=60, **kw)


@pytest.mark.parametrize("args,needle", [
    (("--map", "nosuch", "--robots", "2", "--alg", "CR"), "unknown map 'nosuch'"),
    (("--map", "grid", "--robots", "0", "--alg", "CR"), "team size must be >= 1"),
    (("--map", "grid", "--robots", "2", "--alg", "XX"), "unknown algorithm 'XX'"),
    (("--map", "grid", "--robots", "two", "--alg", "CR"), "invalid int value: 'two'"),
    (("--map", "grid", "--robots", "2", "--alg", "CR", "--speedup", "fast"),
     "argument --speedup: must be a number > 0 or auto, got 'fast'"),
    (("--map", "grid", "--robots", "2", "--alg", "CR", "--speedup", "0"),
     "argument --speedup: must be a number > 0 or auto, got '0'"),
    (("--map", "grid", "--robots", "2", "--alg", "CR", "--speedup", "auto"),
     "argument --speedup: auto needs --nav abstract"),
    (("grid", "4", "default", "CR", "AMCL", "ros", "x", "0", "xterm", "60"),
     "argument GWAIT: expected float"),
    (("--config", "/nonexistent/c.yaml"), "configuration file not found"),
    ((), "no display for the GUI"),
    (("--batch", "/nonexistent/b.yaml"), "batch file not found"),
])
def test_cli_errors_before_anything_starts(args, needle, tmp_path):
    r = _cli(*args, "--results-dir", str(tmp_path / "res")) if args and args[0].startswith(
        "--m") else _cli(*args)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr
    assert not (tmp_path / "res").exists() or not any((tmp_path / "res").rglob("*.csv"))


def test_cli_dry_run_writes_launch_and_config(tmp_path):
    r = _cli("--map", "grid", "--robots", "3", "--alg", "CR", "--loc", "fake_localization",
             "--timeout", "60", "--results-dir", str(tmp_path), "--dry-run")
    assert r.returncode == 0, r.stderr
    launch = [l.split(": ", 1)[1] for l in r.stdout.splitlines() if l.startswith("launch file")][0]
    assert os.path.isfile(launch)
    cfg = load_config_file(launch.replace("_experiment.launch", "_config.yaml"))
    assert (cfg.map, cfg.robots, cfg.alg, cfg.timeout) == ("grid", 3, "CR", 60.0)
    assert os.path.dirname(launch).endswith(os.path.join("grid_3", "CR", os.uname().nodename))


def test_speedup_auto_in_the_abstract_world(tmp_path):
    cfg = ExperimentConfig().updated({"map": "grid", "robots": 2, "alg": "CR",
                                      "nav": "abstract", "speedup": "Auto",
                                      "results_dir": str(tmp_path)}).validate()
    assert cfg.speedup == 0.0                       # the abstract world's "not paced"
    assert "speedup: auto" in cfg.to_yaml()
    path = tmp_path / "c.yaml"
    path.write_text(cfg.to_yaml())
    assert load_config_file(str(path)).speedup == 0.0       # read back
    # the default: auto in the abstract world, real time on the full stack
    base = {"map": "grid", "robots": 2, "alg": "CR", "results_dir": str(tmp_path)}
    assert ExperimentConfig().updated(dict(base, nav="abstract")).validate().speedup == 0.0
    assert ExperimentConfig().updated(base).validate().speedup == 1.0


def test_patrol_agents_robot_ids():
    from patrolling_sim.ros.agent_params import AgentError, parse_ids
    assert parse_ids(["0-3"]) == [0, 1, 2, 3]
    assert parse_ids(["5", "0-1", "1"]) == [0, 1, 5]
    for bad in (["x"], ["3-1"], ["-2"]):
        with pytest.raises(AgentError):
            parse_ids(bad)


def test_batch_exit_status_of_a_child_killed_by_a_signal():
    from patrolling_sim.runner.batch import exit_status
    assert exit_status(-2) == 130 and exit_status(-15) == 143      # as a shell reports them
    assert exit_status(0) == 0 and exit_status(3) == 3 and exit_status(None) is None


@pytest.mark.parametrize("processes", ["shared", "separate"])
def test_ros_agents_get_graph_modes_seeds(processes, tmp_path, monkeypatch):
    """With the same run seed a robot's agent is seeded alike in ROS mode and in graph mode
    (agent_core.agent_seed), so its strategy draws the same numbers (RAND's walk, the start
    delay) in both modes."""
    from patrolling_sim.graphsim import simulator as graph_sim
    from patrolling_sim.graphsim.config import GraphSimConfig
    from patrolling_sim.agent.factory import agent_seed
    cfg = base(results_dir=str(tmp_path), processes=processes, seed=3).validate()
    root = ET.fromstring(generate_launch(cfg, cfg.start_positions(), str(tmp_path / "p")))
    if processes == "shared":
        (node,) = [n for n in root.iter("node") if n.get("type") == "patrol_agents"]
        # patrol_agents gives agent i the node's ~seed + i
        ros = [int(node.find("param[@name='seed']").get("value")) + i for i in range(4)]
    else:
        ros = [int(n.find("param[@name='seed']").get("value"))
               for n in root.iter("node") if n.get("type") == "patrol_agent"]
    seen = []
    real = graph_sim.build_agent
    monkeypatch.setattr(graph_sim, "build_agent",
                        lambda *a, **kw: seen.append(kw["seed"]) or real(*a, **kw))
    graph_sim.GraphSimulator(GraphSimConfig(map="grid", robots=4, alg="RAND", seed=3,
                                            duration=5.0)).run(write=False)
    assert ros == seen == [agent_seed(3, i) for i in range(4)] == [3001, 3002, 3003, 3004]
