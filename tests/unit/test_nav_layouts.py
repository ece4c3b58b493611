"""``--processes`` layouts with pooled navigation (pooled[:K], pooled-separate[:K]): parsing
and one-line errors, the generated launch (nav_host processes, per-robot parameters only),
robot_nav.launch with ``nodes:=false``, and the memory estimate. No ROS master needed."""
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET

import pytest

from patrolling_sim import validation
from patrolling_sim.errors import PatrolInputError
from patrolling_sim.runner.config import ExperimentConfig, process_layout
from patrolling_sim.runner.launchgen import generate_launch

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def base(**kw):
    d = dict(map="grid", robots=5, alg="CGG", loc="fake_localization", timeout=300.0)
    d.update(kw)
    return ExperimentConfig(**d)


@pytest.mark.parametrize("value,robots,expected", [
    ("shared", 4, ("shared", "robot_nav", 0)),
    ("separate", 4, ("separate", "separate", 0)),
    ("pooled", 4, ("shared", "pooled", 1)),
    ("pooled", 12, ("shared", "pooled", 2)),
    ("pooled:3", 12, ("shared", "pooled", 3)),
    ("pooled-separate", 4, ("separate", "pooled", 1)),
    ("pooled-separate:2", 4, ("separate", "pooled", 2)),
    ("pooled:1", 1, ("shared", "pooled", 1)),
])
def test_process_layout(value, robots, expected):
    assert process_layout(value, robots) == expected


@pytest.mark.parametrize("value,needle", [
    ("threads", "must be one of shared, separate, pooled[:K], pooled-separate[:K]"),
    ("shared:2", "must be one of"),
    ("pooled:0", "K in 'pooled:0' must be an integer from 1 to the number of robots (5)"),
    ("pooled:6", "from 1 to the number of robots (5)"),
    ("pooled:x", "must be an integer"),
    ("pooled-separate:-1", "must be an integer"),
])
def test_process_layout_errors(value, needle, tmp_path):
    with pytest.raises(PatrolInputError) as ei:
        base(processes=value, results_dir=str(tmp_path)).validate()
    msg = str(ei.value)
    assert msg.startswith("argument --processes:") and needle in msg and "\n" not in msg


def test_pooled_needs_our_navigation(tmp_path):
    with pytest.raises(PatrolInputError, match="argument --processes: 'pooled' pools"):
        base(processes="pooled", nav="ros", results_dir=str(tmp_path)).validate()


def launch(tmp_path, **kw):
    cfg = base(results_dir=str(tmp_path), **kw).validate()
    return ET.fromstring(generate_launch(cfg, cfg.start_positions(), str(tmp_path / "x")))


@pytest.mark.parametrize("processes,agents", [("pooled:2", "shared"),
                                              ("pooled-separate:2", "separate")])
def test_pooled_launch(processes, agents, tmp_path):
    root = launch(tmp_path, processes=processes, loc="AMCL")
    hosts = [n for n in root.iter("node") if n.get("type") == "nav_host"]
    assert [h.get("name") for h in hosts] == ["nav_host_0", "nav_host_1"]
    lists = [h.find("param[@name='robots']").get("value").split() for h in hosts]
    # every robot hosted exactly once, in blocks of (almost) equal size
    assert sum(lists, []) == [f"robot_{i}" for i in range(5)]
    assert sorted(len(x) for x in lists) == [2, 3]
    assert all(h.find("param[@name='localization']").get("value") == "AMCL" for h in hosts)
    assert all(h.find("param[@name='map_yaml']").get("value").endswith(".yaml") for h in hosts)
    # room in the plan cache for every patrol vertex of grid (25)
    assert all(h.find("param[@name='plan_cache_goals']").get("value") == "25" for h in hosts)
    # per-robot includes set the parameters only
    for inc in (i for i in root.iter("include") if i.get("file").endswith("robot.launch")):
        args = {a.get("name"): a.get("value") for a in inc.iter("arg")}
        assert args["nav_nodes"] == "false"
    group = [g for g in root.iter("group") if g.get("ns") == "nav_pool"][0]
    assert group.find("param[@name='actionlib_status_frequency']").get("value") == "1.0"
    one_host = [n for n in root.iter("node") if n.get("type") == "patrol_agents"]
    per_robot = [n for n in root.iter("node") if n.get("type") == "patrol_agent"]
    if agents == "shared":
        assert len(one_host) == 1 and not per_robot
    else:
        assert not one_host and len(per_robot) == 5


def test_shared_layout_has_no_nav_host(tmp_path):
    root = launch(tmp_path)
    assert not [n for n in root.iter("node") if n.get("type") == "nav_host"]
    for inc in (i for i in root.iter("include") if i.get("file").endswith("robot.launch")):
        assert "nav_nodes" not in {a.get("name") for a in inc.iter("arg")}


@pytest.mark.parametrize("processes", ["shared", "separate", "pooled:2", "pooled-separate"])
def test_every_navigation_process_gets_the_plan_store(processes, tmp_path, monkeypatch):
    monkeypatch.setenv("PATROLLING_SIM_PLAN_STORE", str(tmp_path / "store"))
    root = launch(tmp_path, processes=processes)
    hosts = [n for n in root.iter("node") if n.get("type") == "nav_host"]
    per_robot = {p.get("name"): p.get("value") for p in root.findall("param")
                 if p.get("name").endswith("/move_base/plan_store")}
    if hosts:
        assert all(h.find("param[@name='plan_store']").get("value") == str(tmp_path / "store")
                   for h in hosts) and not per_robot
    else:
        assert per_robot == {f"robot_{i}/move_base/plan_store": str(tmp_path / "store")
                             for i in range(5)}
    monkeypatch.setenv("PATROLLING_SIM_PLAN_STORE", "none")
    root = launch(tmp_path, processes=processes)
    assert "plan_store" not in ET.tostring(root, encoding="unicode")


def test_the_abstract_world_has_no_plan_store(tmp_path, monkeypatch):
    monkeypatch.setenv("PATROLLING_SIM_PLAN_STORE", str(tmp_path / "store"))
    assert "plan_store" not in ET.tostring(launch(tmp_path, nav="abstract"), encoding="unicode")


@pytest.mark.skipif(shutil.which("roslaunch", path="/usr/bin") is None,
                    reason="roslaunch not installed")
def test_robot_launch_without_nodes_sets_the_same_parameters():
    env = dict(os.environ, ROS_PACKAGE_PATH=os.path.join(ROOT, "src"),
               PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))
    path = os.path.join(ROOT, "launch", "robot.launch")

    def query(option, *args):
        p = subprocess.run(["/usr/bin/roslaunch", option, path, "robotname:=robot_2",
                            "localization:=AMCL", "map_yaml:=/m.yaml", *args], env=env,
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 0, p.stderr
        return p.stdout
    import yaml
    assert query("--nodes", "nav_nodes:=false").split() == []
    pooled = yaml.safe_load(query("--dump-params", "nav_nodes:=false"))
    alone = yaml.safe_load(query("--dump-params", "combined:=false"))
    assert pooled == alone and pooled["/robot_2/amcl/odom_frame_id"] == "robot_2/odom"


def test_memory_estimate_per_layout():
    m = validation.MEMORY_MB
    assert validation.memory_estimate_mb(12, "shared") == m["fixed"] + 12 * m["per_robot"]["shared"]
    pooled = validation.memory_estimate_mb(64, "pooled:2")
    assert pooled == m["fixed"] + 2 * m["per_nav_host"] + 64 * m["per_robot"]["pooled"]
    assert validation.memory_estimate_mb(64, "pooled") == pooled      # default K = 2 here
    assert pooled < validation.memory_estimate_mb(64, "shared")
    assert pooled < 8 * 1024
    with pytest.raises(PatrolInputError) as ei:
        validation.check_memory(64, "pooled-separate:4", available=1000.0)
    assert "4 nav_host x" in str(ei.value) and "\n" not in str(ei.value)
