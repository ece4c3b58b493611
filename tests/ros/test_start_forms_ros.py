"""Stated start vertices in ROS mode: the abstract world (``--nav abstract``) started through
scripts/start_experiments.py with ``--initpos vertices:...`` puts the robots on those
vertices, and their first decisions are graph mode's with the same starts and seed."""
import glob
import os
import subprocess
import sys

import pytest
import yaml

from rosenv import ros_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402
from patrolling_sim.monitor.metrics import read_visits  # noqa: E402

VERTS = [21, 8, 3]
INITPOS = "vertices:" + ",".join(map(str, VERTS))
SEED = 3


def first_two_visits(prefix):
    """robot -> [its first visit (the start vertex), its second (its first goal)]."""
    out = {}
    for _, robot, vertex in read_visits(prefix + "_visits.csv"):
        out.setdefault(robot, [])
        if len(out[robot]) < 2:
            out[robot].append(vertex)
    return out


@pytest.mark.parametrize("alg", ("CGG", "SEBS"))
def test_abstract_world_starts_on_stated_vertices_and_decides_as_graph_mode(tmp_path, alg):
    res = tmp_path / "ros"
    res.mkdir()
    proc = subprocess.run(["/usr/bin/python3", START, "--headless", "--map", "grid",
                           "--robots", "3", "--alg", alg, "--nav", "abstract", "--timeout",
                           "60", "--speedup", "10", "--seed", str(SEED), "--initpos", INITPOS,
                           "--results-dir", str(res)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          env=ros_env(), cwd=str(res), timeout=600, start_new_session=True)
    assert proc.returncode == 0, proc.stdout[-3000:]
    (info,) = glob.glob(f"{res}/**/*_info.csv", recursive=True)
    prefix = info[:-len("_info.csv")]
    with open(prefix + "_start_poses.txt") as f:
        assert [int(line.split()[3]) for line in f if not line.startswith("#")] == VERTS
    with open(prefix + "_config.yaml") as f:
        assert yaml.safe_load(f)["start_vertices"] == VERTS
    ros = first_two_visits(prefix)

    cfg = GraphSimConfig(map="grid", robots=3, alg=alg, duration=60.0, seed=SEED,
                         initpos=INITPOS, results_dir=str(tmp_path / "graph"))
    sim = GraphSimulator(cfg)
    sim.run()
    graph = first_two_visits(sim.prefix)
    assert [graph[i][0] for i in range(3)] == VERTS
    assert all(len(ros[i]) == 2 for i in range(3)), ros
    assert ros == graph, f"ROS mode {ros}, graph mode {graph}"
