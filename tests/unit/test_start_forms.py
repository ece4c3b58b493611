"""Start positions a user states (``--initpos vertices:...``, a start file of poses or
vertices, an ``[InitialPoses]`` file) and random ones (``--initpos random``, seeded by the
run's seed): graph mode starts the robots there (read back from ``_start_poses.txt``,
``_config.yaml`` and the first visit reports), campaigns record them, bad values are one-line
errors before anything is written."""
import dataclasses
import glob
import io
import os
import subprocess
import sys

import pandas as pd
import pytest
import yaml

from patrolling_sim.campaign.engine import run_campaign
from patrolling_sim.campaign.spec import load_campaign
from patrolling_sim.campaign.tasks import WorldCache
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.model import map_bundle
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.monitor.metrics import read_visits
from patrolling_sim.runner.config import ExperimentConfig, load_config_file
from patrolling_sim.startpos.explicit import parse_initpos, random_start_vertices
from patrolling_sim.startpos.explicit import usable_vertices
from patrolling_sim.startpos.resolve import start_positions

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
GRAPH_SIM = os.path.join(ROOT, "scripts", "graph_sim.py")
GRAPH_TOOL = os.path.join(ROOT, "scripts", "graph_tool.py")
START = os.path.join(ROOT, "scripts", "start_experiments.py")
#: three grid vertices and their coordinates (maps/grid/grid.graph)
VERTS = [21, 8, 3]
XY = {21: (24.225, 18.675), 8: (7.125, 7.275), 3: (1.425, 7.275)}
#: an occupied cell of the grid map (a block between the corridors)
OCCUPIED = (4.0, 4.0)


def _grid():
    occ, G = map_bundle.load_map_bundle("grid")
    return occ, PatrolGraph(G)


def drawn(n, seed):
    """The random start vertices of ``n`` robots on grid with ``seed``."""
    occ, pg = _grid()
    return random_start_vertices(pg, n, seed, usable_vertices(pg, occ))


def run_graph(tmp_path, initpos, robots=3, seed=0, alg="CGG", duration=120.0):
    """One graph-mode run; (prefix, start vertices of _start_poses.txt, of _config.yaml, the
    vertex of each robot's first visit report)."""
    cfg = GraphSimConfig(map="grid", robots=robots, alg=alg, duration=duration, seed=seed,
                         initpos=initpos, results_dir=str(tmp_path / "res"))
    sim = GraphSimulator(cfg)
    sim.run()
    return sim.prefix, read_starts(sim.prefix)


def read_starts(prefix):
    """(start_poses vertices, config start_vertices, first visit per robot) of a run."""
    with open(prefix + "_start_poses.txt") as f:
        rows = [line.split() for line in f if not line.startswith("#")]
    assert [int(r[0]) for r in rows] == list(range(len(rows)))
    poses = [int(r[3]) for r in rows]
    with open(prefix + "_config.yaml") as f:
        recorded = yaml.safe_load(f)["start_vertices"]
    first = {}
    for _, robot, vertex in read_visits(prefix + "_visits.csv"):
        first.setdefault(robot, vertex)
    return poses, recorded, [first[i] for i in range(len(rows))]


def _write(path, text):
    path.write_text(text)
    return str(path)


# -- each form, in graph mode ---------------------------------------------------------------
def test_vertex_list_starts_the_robots_on_those_vertices(tmp_path):
    prefix, (poses, recorded, first) = run_graph(tmp_path, "vertices:21,8,3")
    assert poses == recorded == first == VERTS
    with open(prefix + "_config.yaml") as f:
        assert yaml.safe_load(f)["initpos"] == "vertices:21,8,3"


def test_pose_table_file_starts_on_the_nearest_vertices(tmp_path):
    # poses 0.3 m off the vertices, in another order, with comments and blank lines
    path = _write(tmp_path / "poses.txt",
                  "# robot x y\n\n2 1.425 7.575   # near vertex 3\n"
                  "0 24.525 18.675\n1 7.125 6.975\n")
    _, (poses, recorded, first) = run_graph(tmp_path, path)
    assert poses == recorded == first == VERTS


def test_a_runs_start_poses_file_replays_its_starts(tmp_path):
    """A run's own _start_poses.txt (robot x y vertex) starts another run the same way."""
    prefix, (poses, _, _) = run_graph(tmp_path / "first", "random", seed=5)
    _, (again, recorded, first) = run_graph(tmp_path / "second", prefix + "_start_poses.txt")
    assert again == recorded == first == poses


def test_vertex_table_file_by_prefix_and_relative_to_the_map_folder(tmp_path, monkeypatch):
    path = _write(tmp_path / "verts.txt", "0 21\n1 8\n2 3\n")
    _, (poses, recorded, first) = run_graph(tmp_path, "file:" + path)
    assert poses == recorded == first == VERTS
    # a relative path is read in the map's folder (here: a copy of the grid map)
    mapdir = tmp_path / "mygrid"
    mapdir.mkdir()
    for ext in ("yaml", "graph", "pgm"):
        src = os.path.join(ROOT, "maps", "grid", "grid." + ext)
        (mapdir / ("mygrid." + ext)).write_bytes(open(src, "rb").read())
    text = (mapdir / "mygrid.yaml").read_text().replace("grid.pgm", "mygrid.pgm")
    (mapdir / "mygrid.yaml").write_text(text)
    _write(mapdir / "team.txt", "0 8\n1 3\n2 21\n")
    monkeypatch.chdir(tmp_path)
    cfg = GraphSimConfig(map=str(mapdir / "mygrid.yaml"), robots=3, alg="CR", duration=30,
                         initpos="team.txt", results_dir=str(tmp_path / "res2"))
    sim = GraphSimulator(cfg)
    sim.run()
    assert read_starts(sim.prefix)[0] == [8, 3, 21]


def test_ini_file_takes_the_map_key_or_the_only_key(tmp_path):
    flat = ", ".join(f"{c}" for v in VERTS for c in XY[v])
    path = _write(tmp_path / "ini.txt", f"[InitialPoses]\ngrid_2: [1.425, 24.375, 12.825, "
                                        f"18.675]\ngrid_3: [{flat}]\n")
    _, (poses, recorded, first) = run_graph(tmp_path, path)
    assert poses == recorded == first == VERTS
    only = _write(tmp_path / "only.ini", f"[InitialPoses]\nmine: [{flat}]\n")
    _, (poses, _, first) = run_graph(tmp_path, "file:" + only)
    assert poses == first == VERTS


def test_random_starts_are_the_seeds_and_change_no_other_draw(tmp_path):
    prefix, (poses, recorded, first) = run_graph(tmp_path, "random", seed=7, alg="SEBS")
    assert poses == recorded == first == drawn(3, 7)
    # the draw has its own generator: the run equals one with these vertices stated
    again, _ = run_graph(tmp_path / "b", "vertices:" + ",".join(map(str, drawn(3, 7))),
                         seed=7, alg="SEBS")
    assert open(prefix + "_visits.csv").read() == open(again + "_visits.csv").read()
    with open(prefix + "_start_poses.txt") as f:
        assert f.readline().strip() == "# start poses: --initpos random --seed 7"


def test_random_is_reproducible_distinct_and_varies_with_the_seed():
    occ, pg = _grid()
    assert usable_vertices(pg, occ) == list(range(pg.n))       # a robot fits on each
    assert drawn(4, 3) == drawn(4, 3)
    draws = {tuple(drawn(4, s)) for s in range(10)}
    assert len(draws) == 10                                     # each seed its own start
    for s in range(10):
        full = drawn(pg.n, s)
        assert sorted(full) == list(range(pg.n))                # N = V: every vertex once
        over = drawn(pg.n + 5, s)
        assert sorted(over[:pg.n]) == list(range(pg.n))         # N > V: all once, then again
        assert len(set(over[pg.n:])) == 5


# -- campaigns ------------------------------------------------------------------------------
def test_campaign_over_seeds_uses_and_records_one_start_each(tmp_path):
    path = _write(tmp_path / "c.yaml", yaml.safe_dump({
        "name": "starts", "mode": "graph", "fixed": {"duration": 60, "robots": 3},
        "grid": {"map": ["grid"], "alg": ["CR"], "initpos": ["random"]}, "seeds": 3}))
    camp = load_campaign(path, code={"commit": "test", "dirty": False})
    out = str(tmp_path / "out")
    res = run_campaign(camp, out, workers=1, stream=io.StringIO())
    assert res["ran"] == 3 and not res["interrupted"]
    df = pd.read_csv(res["table"])
    assert list(df.columns)[-1] == "start_vertices"
    starts = {}
    for _, row in df.iterrows():
        got = [int(v) for v in str(row["start_vertices"]).split()]
        assert got == drawn(3, int(row["seed"]))
        assert got == read_starts(os.path.join(out, row["prefix"]))[0]
        starts[int(row["seed"])] = tuple(got)
    assert sorted(starts) == [0, 1, 2] and len(set(starts.values())) == 3


def test_worker_cache_keys_random_on_the_seed_and_a_file_on_its_stamp(tmp_path):
    worlds = WorldCache()
    cfg = GraphSimConfig(map="grid", robots=3, alg="CR", initpos="random")
    a = worlds.get(dataclasses.replace(cfg, seed=1))[1]
    b = worlds.get(dataclasses.replace(cfg, seed=2))[1]
    assert a != b and worlds.get(dataclasses.replace(cfg, seed=1))[1] == a
    assert list(a) == drawn(3, 1) and list(b) == drawn(3, 2)
    path = tmp_path / "s.txt"
    _write(path, "0 21\n1 8\n2 3\n")
    fcfg = GraphSimConfig(map="grid", robots=3, alg="CR", initpos=str(path))
    assert list(worlds.get(fcfg)[1]) == VERTS
    _write(path, "0 3\n1 21\n2 8\n\n")
    assert list(worlds.get(fcfg)[1]) == [3, 21, 8]


# -- bad values -----------------------------------------------------------------------------
def _bad_cases(tmp_path):
    missing = str(tmp_path / "missing.txt")
    malformed = _write(tmp_path / "malformed.txt", "0 21\n1 eight\n2 3\n")
    occupied = _write(tmp_path / "occupied.txt",
                      f"0 21\n1 {OCCUPIED[0]} {OCCUPIED[1]}\n2 3\n")
    return [("vertices:21,99,3", "vertex 99 does not exist"),
            ("vertices:21,8", "'vertices:21,8' gives 2 start vertices, the team has 3"),
            ("file:" + missing, f"{missing}: start positions file not found"),
            (malformed, f"{malformed}:2: expected 'robot x y' or 'robot vertex'"),
            (occupied, "robot 1 at (4.000, 4.000) is on an occupied cell")]


@pytest.mark.parametrize("case", range(5))
def test_bad_start_is_one_line_exit_2_and_nothing_written(tmp_path, case):
    initpos, needle = _bad_cases(tmp_path)[case]
    res = tmp_path / "res"
    p = subprocess.run([sys.executable, GRAPH_SIM, "--map", "grid", "--robots", "3", "--alg",
                        "CR", "--duration", "30", "--initpos", initpos, "--results-dir",
                        str(res)], capture_output=True, text=True, timeout=120)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert "argument --initpos" in lines[0] and needle in lines[0], lines[0]
    assert not res.exists()


def test_stated_starts_checked_in_process(tmp_path):
    occ, pg = _grid()

    def starts(n, text):
        return start_positions("grid", n, pg, occ, "file:" + _write(tmp_path / "s.txt", text))
    with pytest.raises(PatrolInputError, match=r"'vertices:21,x': expected comma-separated"):
        parse_initpos("vertices:21,x")
    with pytest.raises(PatrolInputError, match=r"robot 0 at \(-50.000, -50.000\) is off the map"):
        starts(1, "0 -50 -50\n")
    with pytest.raises(PatrolInputError, match="robot 1 is given twice"):
        starts(2, "0 21\n1 8\n1 3\n")
    with pytest.raises(PatrolInputError, match="robot 2 is not in the team"):
        starts(2, "0 21\n2 8\n")
    with pytest.raises(PatrolInputError, match="robots 0 and 1 are 0.10 m apart"):
        starts(2, "0 1.425 7.275\n1 1.525 7.275\n")
    with pytest.raises(PatrolInputError, match="no key 'grid_2' and 2 other keys"):
        starts(2, "[InitialPoses]\na: [1.425, 7.275, 7.125, 7.275]\nb: [1.425, 7.275]\n")
    with pytest.raises(PatrolInputError, match="key 'a' has 1 poses, the team has 2"):
        starts(2, "[InitialPoses]\na: [1.425, 7.275]\n")
    assert parse_initpos("default") is None and parse_initpos("a") is None
    assert parse_initpos("optimised") is None and parse_initpos("starts.txt").kind == "file"
    assert parse_initpos("sub/starts").kind == "file" and parse_initpos("random").kind == "random"


def test_two_robots_on_one_vertex_is_a_warning_not_an_error(tmp_path, caplog):
    prefix, (poses, recorded, first) = run_graph(tmp_path, "vertices:21,21,3")
    assert poses == recorded == first == [21, 21, 3]
    assert "robots 0 and 1 start on vertex 21" in caplog.text


# -- the runner and graph_tool --------------------------------------------------------------
def test_runner_records_the_start_vertices_and_reads_its_config_back(tmp_path):
    p = subprocess.run([sys.executable, START, "--headless", "--map", "grid", "--robots", "3",
                        "--alg", "CR", "--nav", "abstract", "--timeout", "60",
                        "--initpos", "vertices:21,8,3", "--results-dir", str(tmp_path),
                        "--dry-run"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    (config,) = glob.glob(str(tmp_path / "**" / "*_config.yaml"), recursive=True)
    prefix = config[:-len("_config.yaml")]
    with open(config) as f:
        rec = yaml.safe_load(f)
    assert rec["initpos"] == "vertices:21,8,3" and rec["start_vertices"] == VERTS
    assert list(rec)[list(rec).index("initpos") + 1] == "start_vertices"
    with open(prefix + "_start_poses.txt") as f:
        assert [int(line.split()[3]) for line in f if not line.startswith("#")] == VERTS
    cfg = load_config_file(config)
    assert cfg.initpos == "vertices:21,8,3" and not hasattr(cfg, "start_vertices")
    bad = ExperimentConfig(map="grid", robots=3, alg="CR", initpos="vertices:1,2",
                           nav="abstract", results_dir=str(tmp_path))
    with pytest.raises(PatrolInputError, match="gives 2 start vertices"):
        bad.validate()


def test_graph_tool_startposes_prints_each_form(tmp_path):
    def vertices(*args):
        p = subprocess.run([sys.executable, GRAPH_TOOL, "startposes", "grid", "3", *args],
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr
        return [int(line.split()[-1]) for line in p.stdout.splitlines()
                if line.startswith("robot_")]
    assert vertices("--initpos", "vertices:21,8,3") == VERTS
    assert vertices("--initpos", _write(tmp_path / "v.txt", "0 21\n1 8\n2 3\n")) == VERTS
    assert vertices("--initpos", "random", "--seed", "5") == drawn(3, 5)
    _, (poses, _, _) = run_graph(tmp_path, "random", seed=5)
    assert poses == drawn(3, 5)
