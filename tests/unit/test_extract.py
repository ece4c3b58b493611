"""Patrol-graph extraction (extract.py), coverage (coverage.py), the graph_tool
sub-commands init-map / extract / coverage, and a new floor plan from image to graph-mode run."""
import os
import subprocess

import numpy as np
import pytest

from patrolling_sim.common import paths
from patrolling_sim.extraction.coverage import check_graph, coverage
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.extraction.extract import (ExtractionParams, extract_graph, init_map_yaml)
from patrolling_sim.model.graph import PatrolGraph, load_graph
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.config import GraphSimConfig
from spqrel_nav_lite.mapio import OccupancyMap, load_map

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
TOOL = os.path.join(ROOT, "scripts", "graph_tool.py")


def floor_plan(path, rooms=4):
    """A floor plan no shipped map resembles: a 1.2 m corridor with ``rooms`` rooms (3 x 3.2 m)
    on each side, each behind a 1 m door in a 0.3 m wall; 0.05 m per pixel."""
    import cv2
    w = 20 + rooms * 70
    img = np.zeros((200, w), np.uint8)
    img[88:112, 10:w - 10] = 255
    for k in range(rooms):
        x0 = 15 + k * 70
        img[20:84, x0:x0 + 60] = 255
        img[83:89, x0 + 20:x0 + 40] = 255
        img[116:180, x0:x0 + 60] = 255
        img[111:117, x0 + 20:x0 + 40] = 255
    assert cv2.imwrite(str(path), img)
    return str(path)


def run_tool(*args):
    """graph_tool.py in this process (as its entry point runs it): (returncode, stdout, stderr)."""
    import contextlib
    import io
    from patrolling_sim.common.cli import run_main
    from patrolling_sim.extraction.graph_tool import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = run_main(main, "graph_tool.py", list(args))
        except SystemExit as e:         # argparse errors
            rc = e.code
    return subprocess.CompletedProcess(args, rc, out.getvalue(), err.getvalue())


def test_script_entry_point(tmp_path):
    r = subprocess.run(["/usr/bin/python3", TOOL, "extract", "grid", "--spacing", "0"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.strip() == \
        "graph_tool.py: error: argument --spacing: must be > 0 metres, got 0"


def test_floor_plan_image_to_graph_mode_run(tmp_path):
    img = floor_plan(tmp_path / "plan.png")
    r = run_tool("init-map", img, "--resolution", "0.05")
    assert r.returncode == 0, r.stderr
    yaml_path = str(tmp_path / "plan.yaml")
    r = run_tool("extract", yaml_path)
    assert r.returncode == 0, r.stderr
    assert os.path.isfile(tmp_path / "plan.graph") and os.path.isfile(tmp_path / "plan-graph.png")
    occ = load_map(yaml_path)
    G = load_graph(str(tmp_path / "plan.graph"), warn=False)
    assert check_graph(occ, G, path_clearance=ExtractionParams().clearance) == []
    pg = PatrolGraph(G)
    # what a person draws: one vertex per room, one junction per door pair on the corridor
    degrees = sorted(pg.degree(v) for v in range(pg.n))
    assert degrees == [1] * 8 + [3, 3, 4, 4], degrees
    rooms = [v for v in range(pg.n) if pg.degree(v) == 1]
    assert all(abs(pg.pos[v][1] - 5.0) > 1.8 for v in rooms)      # in the rooms
    assert coverage(occ, pg) > 0.97
    # graph-mode run on it: every vertex visited
    cfg = GraphSimConfig(map=yaml_path, robots=2, alg="CGG", duration=600, seed=3,
                         results_dir=str(tmp_path / "res"), initpos="optimised")
    sim = GraphSimulator(cfg)
    stats = sim.run()
    assert stats.cycles >= 1
    rows = open(sim.prefix + "_idleness.csv").read().splitlines()[1:]
    assert {int(r.split(";")[2]) for r in rows} == set(range(pg.n))
    assert os.path.isfile(sim.prefix + "_start_poses.txt")


def test_extract_is_deterministic_and_refuses_to_overwrite(tmp_path):
    img = floor_plan(tmp_path / "p.png", rooms=2)
    init_map_yaml(img, 0.05)
    y = str(tmp_path / "p.yaml")
    assert run_tool("extract", y).returncode == 0
    first = open(tmp_path / "p.graph").read()
    r = run_tool("extract", y)
    assert r.returncode != 0 and "exists" in r.stderr and len(r.stderr.splitlines()) == 1
    assert run_tool("extract", y, "--force").returncode == 0
    assert open(tmp_path / "p.graph").read() == first
    # spacing: more vertices along the corridor with a smaller spacing
    q = str(tmp_path / "q.graph")
    assert run_tool("extract", y, "--out", q, "--spacing", "1").returncode == 0
    assert load_graph(q).number_of_nodes() > \
        load_graph(str(tmp_path / "p.graph")).number_of_nodes()


@pytest.mark.parametrize("case", ["no_free", "disconnected", "spacing0", "spacing_neg",
                                  "resolution0", "no_image"])
def test_bad_inputs_one_line(tmp_path, case):
    import cv2
    if case == "no_free":
        cv2.imwrite(str(tmp_path / "m.png"), np.zeros((40, 40), np.uint8))
    elif case == "disconnected":
        img = np.zeros((100, 200), np.uint8)
        img[10:90, 10:90] = 255
        img[10:90, 110:190] = 255
        cv2.imwrite(str(tmp_path / "m.png"), img)
    else:
        floor_plan(tmp_path / "m.png", rooms=1)
    if case == "no_image":
        r = run_tool("init-map", str(tmp_path / "none.png"), "--resolution", "0.05")
    elif case == "resolution0":
        r = run_tool("init-map", str(tmp_path / "m.png"), "--resolution", "0")
    else:
        assert run_tool("init-map", str(tmp_path / "m.png"), "--resolution", "0.05").returncode == 0
        extra = {"spacing0": ["--spacing", "0"], "spacing_neg": ["--spacing", "-2"]}.get(case, [])
        r = run_tool("extract", str(tmp_path / "m.yaml"), *extra)
    assert r.returncode != 0
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("graph_tool.py: error: "), r.stderr
    want = {"no_free": "no free cell", "disconnected": "2 disconnected pieces",
            "spacing0": "--spacing", "spacing_neg": "--spacing",
            "resolution0": "--resolution", "no_image": "not found"}[case]
    assert want in lines[0]
    if case == "disconnected":      # names the pieces (area and centre in metres)
        assert "around (2.5, 2.5)" in lines[0] and "around (7.5, 2.5)" in lines[0]
    assert not os.path.exists(tmp_path / "m.graph")


def test_disconnected_largest_option(tmp_path):
    data = np.full((100, 220), 100, np.int8)
    data[10:90, 10:90] = 0          # 4 x 4 m
    data[10:90, 110:210] = 0        # 5 x 4 m: the largest
    occ = OccupancyMap(data, 0.05)
    with pytest.raises(PatrolInputError, match="disconnected"):
        extract_graph(occ)
    res = extract_graph(occ, ExtractionParams(largest=True))
    assert all(p[0] > 5.4 for p in PatrolGraph(res.graph).pos)
    assert len(res.dropped) == 1


SMALL_MAPS = ["grid", "example", "cumberland", "1r5", "move_base_arena", "ctcv"]


@pytest.mark.parametrize("name", SMALL_MAPS)
def test_shipped_map_acceptance(name):
    """Connected, vertices free with robot clearance, edges traversable, costs within 2 %,
    coverage >= hand-made - 2 points. (All maps, with the table: bench/extract_bench.py.)"""
    yaml_path, graph_path = paths.map_files(name)
    occ = load_map(yaml_path)
    res = extract_graph(occ, name=name)
    assert check_graph(occ, res.graph, path_clearance=ExtractionParams().clearance) == []
    ours = coverage(occ, PatrolGraph(res.graph))
    hand = coverage(occ, PatrolGraph(load_graph(graph_path, warn=False)))
    assert ours >= hand - 0.02, (ours, hand)


def test_check_graph_can_fail():
    """The checker rejects a wrong cost and a wall-crossing edge (hand-made graphs)."""
    occ = load_map(paths.map_files("grid")[0])
    G = load_graph(paths.map_files("grid")[1], warn=False)
    assert check_graph(occ, G) == []
    for _, _, d in G.out_edges(0, data=True):
        d["cost_px"] = 2 * d["cost_px"]
    assert any("costs" in p for p in check_graph(occ, G))
    occ2 = load_map(paths.map_files("example")[0])
    assert check_graph(occ2, load_graph(paths.map_files("example")[1], warn=False))


def test_coverage_cli(tmp_path):
    r = run_tool("coverage", "grid")
    assert r.returncode == 0 and "coverage(5 m, line of sight)=100.0%" in r.stdout, r.stderr
    r = run_tool("coverage", "grid", "--radius", "0")
    assert r.returncode != 0 and len(r.stderr.splitlines()) == 1
