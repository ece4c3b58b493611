"""The runner's scenario options (--comm, --attrition; docs/scenarios.md): defaults,
one-line validation errors, the configuration file keys, the parameters the launch file
gives the nodes, and the dry run through the command line."""
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
import yaml

from patrolling_sim.scenarios.attrition import parse_attrition
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.runner.config import ExperimentConfig, load_config_file
from patrolling_sim.runner.launchgen import generate_launch

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPT = os.path.join(ROOT, "scripts", "start_experiments.py")


def base(tmp_path, **kw):
    d = dict(map="grid", robots=4, alg="SEBS", loc="fake_localization", timeout=300.0,
             results_dir=str(tmp_path))
    d.update(kw)
    return ExperimentConfig(**d)


def launch_of(cfg, tmp_path):
    root = ET.fromstring(generate_launch(cfg, cfg.start_positions(),
                                         str(tmp_path / "20260101_000000")))
    params = {p.get("name"): (p.get("type"), p.get("value")) for p in root.findall("param")}
    mon = [n for n in root.iter("node") if n.get("type") == "monitor"][0]
    mon_params = {p.get("name"): p.get("value") for p in mon.findall("param")}
    return params, mon_params


def test_defaults_are_the_original_behaviour(tmp_path):
    cfg = base(tmp_path).validate()
    assert (cfg.comm, cfg.attrition) == ("perfect", "none")
    model, schedule = cfg.scenario()
    assert model.name == "perfect" and schedule == []
    params, mon = launch_of(cfg, tmp_path)
    assert params["/comm_model"] == ("str", "perfect")
    assert params["/attrition"] == ("str", "none")
    assert params["/scenario_seed"] == ("int", "0")
    assert mon["attrition_spec"] == "none"


def test_launch_parameters_of_a_scenario(tmp_path):
    cfg = base(tmp_path, comm="ge:p_bad=0.9, to_bad=0.1 ;delay=uniform:0.1,0.3",
               attrition="3@120+60, 1@100", seed=7).validate()
    params, mon = launch_of(cfg, tmp_path)
    # canonical model spec, schedule sorted by time, as the nodes parse them back
    assert params["/comm_model"] == (
        "str", "ge:p_good=0,p_bad=0.9,to_bad=0.1,to_good=0.5;delay=uniform:0.1,0.3")
    assert params["/attrition"] == ("str", "1@100.0,3@120.0+60.0")
    assert params["/scenario_seed"] == ("int", "7")
    assert mon["attrition_spec"] == "3@120+60, 1@100"


def test_random_attrition_is_drawn_once_from_the_seed(tmp_path):
    spec = "random:rate=20,min_team=2"
    a = launch_of(base(tmp_path, attrition=spec, seed=3).validate(), tmp_path)[0]["/attrition"]
    b = launch_of(base(tmp_path, attrition=spec, seed=3).validate(), tmp_path)[0]["/attrition"]
    c = launch_of(base(tmp_path, attrition=spec, seed=4).validate(), tmp_path)[0]["/attrition"]
    assert a == b and a != c
    drawn = parse_attrition(a[1], 4)             # explicit form every node reads the same way
    assert drawn == parse_attrition(spec, 4, duration=300.0, seed=3)
    assert drawn and all(f.t <= 300.0 for f in drawn)
    # never fewer than min_team robots working
    assert len({f.robot for f in drawn}) <= 2


@pytest.mark.parametrize("kw,needle", [
    (dict(comm="bluetooth"), "argument --comm: unknown communication model 'bluetooth'"),
    (dict(comm="bernoulli:p=1.5"), "argument --comm: bernoulli: p must be in [0, 1]"),
    (dict(comm="range:r=-1"), "argument --comm: range: r must be > 0 m"),
    (dict(comm="perfect;delay=gamma:1"), "argument --comm: unknown delay distribution"),
    (dict(attrition="4@100"), "argument --attrition: robot 4 is not in a team of 4"),
    (dict(attrition="2@x"), "argument --attrition: expected ROBOT@SECONDS"),
    (dict(attrition="0@1,1@1,2@1,3@1"), "every robot of the team would be gone"),
    (dict(attrition="1@300"), "argument --attrition: robot 1 fails at 300 s, not before the "
                              "end of the run (300 s)"),
    (dict(attrition="random:rate=1", timeout=0.0, cycles=2),
     "argument --attrition: the random model needs a run duration"),
])
def test_validation_errors(tmp_path, kw, needle):
    with pytest.raises(PatrolInputError) as e:
        base(tmp_path, **kw).validate()
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_config_file_keys_round_trip(tmp_path):
    path = tmp_path / "exp.yaml"
    path.write_text("map: grid\nrobots: 3\nalg: DTAP\ncomm: 'range:r=8,los=false'\n"
                    "attrition: '1@150+50'\ntimeout: 300\n")
    cfg = load_config_file(str(path))
    assert (cfg.comm, cfg.attrition) == ("range:r=8,los=false", "1@150+50")
    cfg.results_dir = str(tmp_path)
    cfg.validate()
    again = tmp_path / "again.yaml"
    cfg.save(str(again))
    assert yaml.safe_load(again.read_text())["attrition"] == "1@150+50"
    assert load_config_file(str(again)).comm == "range:r=8,los=false"


def _cli(*args):
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True,
                          env=env, timeout=120)


def test_cli_options(tmp_path):
    common = ("--map", "grid", "--robots", "3", "--alg", "SEBS", "--loc", "fake_localization",
              "--timeout", "300", "--results-dir", str(tmp_path))
    bad = _cli(*common, "--attrition", "5@100", "--dry-run")
    assert bad.returncode == 2
    lines = bad.stderr.strip().splitlines()
    assert lines == [lines[0]] and "argument --attrition: robot 5 is not in a team of 3" in \
        lines[0]
    assert not list(tmp_path.rglob("*_config.yaml"))           # nothing half-written
    ok = _cli(*common, "--comm", "bernoulli:p=0.3", "--attrition", "1@100", "--dry-run")
    assert ok.returncode == 0, ok.stderr
    launch = [l.split(": ", 1)[1] for l in ok.stdout.splitlines()
              if l.startswith("launch file")][0]
    cfg = load_config_file(launch.replace("_experiment.launch", "_config.yaml"))
    assert (cfg.comm, cfg.attrition) == ("bernoulli:p=0.3", "1@100")    # recorded
    text = open(launch).read()
    assert 'name="/comm_model" type="str" value="bernoulli:p=0.3"' in text
    assert 'name="/attrition" type="str" value="1@100.0"' in text


def test_summary_line_reports_failures_and_messages(tmp_path):
    from patrolling_sim.scenarios.attrition import parse_attrition
    from patrolling_sim.runner.cli import scenario_summary
    from patrolling_sim.scenarios.scenario import write_scenario
    prefix = str(tmp_path / "20260101_000000")
    assert scenario_summary(prefix) is None                    # no scenario, no line
    write_scenario(prefix, "bernoulli:p=0.2", "1@80+100,2@150", parse_attrition(
        "1@80+100,2@150", 3), [[1, 80.04, 180.06], [2, 150.0, None]],
        {0: {"sent": 60, "delivered": 45, "lost": 15}, 1: {"sent": 40, "delivered": 35,
                                                           "lost": 5}}, mode="ros")
    assert scenario_summary(prefix) == (
        "scenario: comm bernoulli:p=0.2; failures robot 1 at 80.04 s (back at 180.06 s), "
        "robot 2 at 150 s; messages sent 100, delivered 80, lost 20 (20.0 %)")


@pytest.mark.parametrize("kw, warned", [
    (dict(attrition="2@80", dead_robot_timeout=60.0), True),
    (dict(attrition="2@80", dead_robot_timeout=150.0), False),     # long enough
    (dict(attrition="2@80", dead_robot_timeout=0.0), False),       # 0: no robot declared dead
    (dict(attrition="2@80", dead_robot_timeout=60.0, nav="abstract"), False),  # no bodies
    (dict(dead_robot_timeout=60.0), False),                        # no failures
    (dict(comm="bernoulli:p=0.2", dead_robot_timeout=60.0), False),
])
def test_short_dead_robot_timeout_with_failures_is_warned(tmp_path, caplog, kw, warned):
    """A failed robot's body can block a teammate's goal vertex for about 150 sim s in a
    world with bodies (docs/scenarios.md): a shorter --dead-robot-timeout is warned about,
    and the run still starts (a warning, not an error)."""
    with caplog.at_level("WARNING", logger="patrolling_sim.runner.config"):
        base(tmp_path, **kw).validate()
    lines = [r.getMessage() for r in caplog.records if "--dead-robot-timeout" in r.getMessage()]
    assert bool(lines) == warned, lines
    if warned:
        assert lines[0].startswith("--dead-robot-timeout 60 s with robot failures"), lines
        assert "at least 150 s" in lines[0]
