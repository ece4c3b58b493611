"""The simulator draws the patrol graph the Python core read: the runner passes it as the
stage2d launch args graph_vertices ("x y ..." m) and graph_edges ("u v ..."), not a .graph
path the simulator would parse a second time."""
import os
import xml.etree.ElementTree as ET

from patrolling_sim.model.graph import load_graph
from patrolling_sim.runner.config import ExperimentConfig
from patrolling_sim.runner.launchgen import generate_launch, graph_drawing

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
GRID = os.path.join(ROOT, "maps", "grid", "grid.graph")


def test_graph_drawing_matches_the_graph():
    xy, edges = graph_drawing(GRID)
    G = load_graph(GRID, warn=False)
    nums = [float(t) for t in xy.split()]
    assert len(nums) == 2 * len(G)
    for v in G.nodes:
        x, y = G.nodes[v]["pos"]
        assert abs(nums[2 * v] - x) < 1e-4 and abs(nums[2 * v + 1] - y) < 1e-4
    ids = [int(t) for t in edges.split()]
    pairs = set(zip(ids[::2], ids[1::2]))
    assert pairs == {(min(u, w), max(u, w)) for u, w in G.edges()}
    assert all(u < w for u, w in pairs) and len(pairs) == len(ids) // 2  # each edge once


def test_launch_passes_the_graph_not_the_file():
    cfg = ExperimentConfig(map="grid", robots=2, alg="CR")
    root = ET.fromstring(generate_launch(cfg, [(1.425, 24.375), (1.425, 18.675)], "/tmp/x/p"))
    inc = [i for i in root.iter("include") if "stage2d.launch" in i.get("file")][0]
    args = {a.get("name"): a.get("value") for a in inc.iter("arg")}
    assert "graph_file" not in args
    assert (args["graph_vertices"], args["graph_edges"]) == graph_drawing(GRID)
