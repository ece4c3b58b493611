"""``--processes`` layouts with pooled navigation (pooled[:K], pooled-separate[:K]): parsing
and one-line errors, the generated launch (nav_host processes, per-robot parameters only),
robot_nav.launch with ``nodes:=false``, and the memory estimate. No ROS master needed."""
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET

import pytest

from patrolling_sim.experiment import validation
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.experiment.validation import process_layout
from patrolling_sim.runner.config import ExperimentConfig
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
    path = os.path.join(ROOT, "src", "patrolling_sim", "launch", "robot.launch")

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
    """The runner's estimate adds up the measured parts (validation.MEMORY_MB): per
    navigation process a base and the map's planner cells, per-robot plan caches or each
    nav_host's cache of every patrol goal, agent processes when separate."""
    m = validation.MEMORY_MB
    cells, n_v = validation.map_memory_figures("broughton")
    assert (cells, n_v) == (1000 * 800, 163)        # 0.1 m cells: one planner cell each
    process = m["nav_process"] + m["nav_per_mcell"] * 0.8
    shared = validation.memory_estimate_mb(12, "shared", cells, n_v)
    assert shared == pytest.approx(m["fixed"] + 12 * (process + m["robot_nav_cache"]))
    pooled = validation.memory_estimate_mb(64, "pooled:2", cells, n_v)
    host = process + 163 * cells * 8 / 2**20       # a navigation function per patrol goal
    assert pooled == pytest.approx(m["fixed"] + 2 * host + 64 * m["robot_in_host"])
    assert validation.memory_estimate_mb(64, "pooled", cells, n_v) == pooled   # K = 2 here
    assert pooled < validation.memory_estimate_mb(64, "shared", cells, n_v)
    assert pooled < 8 * 1024
    # grid's planner grid is 7 times smaller; its 25 goals fit in a move_base's cache
    grid_cells, grid_v = validation.map_memory_figures("grid")
    assert (grid_cells, grid_v) == (344 * 344, 25)
    grid_cache = 25 * grid_cells * 8 / 2**20
    assert grid_cache < m["robot_nav_cache"]
    grid_process = m["nav_process"] + m["nav_per_mcell"] * grid_cells / 1e6
    assert validation.memory_estimate_mb(12, "shared", grid_cells, grid_v) == pytest.approx(
        m["fixed"] + 12 * (grid_process + grid_cache))
    assert validation.memory_estimate_mb(12, "shared", grid_cells, grid_v) < shared - 2000
    # separate: a localiser process and an agent process per robot more
    assert validation.memory_estimate_mb(12, "separate", cells, n_v) == pytest.approx(
        shared + 12 * (m["localiser_process"] + m["agent_process"]))
    # the abstract world has no navigation
    assert validation.memory_estimate_mb(12, "shared", cells, n_v, "abstract") == m["fixed"]
    with pytest.raises(PatrolInputError) as ei:
        validation.check_memory(64, "pooled-separate:4", cells, n_v, available=1000.0)
    assert "4 nav_host x" in str(ei.value) and "\n" not in str(ei.value)
