"""Live graph markers (patrolling_sim.ros.markers): pure builder, no ROS master."""
import pytest

pytest.importorskip("visualization_msgs.msg")

from visualization_msgs.msg import Marker  # noqa: E402

from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.model.graph import PatrolGraph, load_graph  # noqa: E402
from patrolling_sim.ros.markers import (build_marker_array, idleness_color,  # noqa: E402
                                        undirected_edges)


@pytest.fixture(scope="module")
def grid():
    return PatrolGraph(load_graph(paths.map_files("grid")[1]))


@pytest.fixture(scope="module")
def example():
    return PatrolGraph(load_graph(paths.map_files("example")[1]))


def by_ns(arr, ns):
    return [m for m in arr.markers if m.ns == ns]


def test_counts_types_and_frame(grid):
    idl = [float(v) for v in range(grid.n)]
    arr = build_marker_array(grid, idl)
    spheres, texts, edges = (by_ns(arr, "vertices"), by_ns(arr, "vertex_ids"),
                             by_ns(arr, "edges"))
    assert len(spheres) == grid.n and len(texts) == grid.n and len(edges) == 1
    assert all(m.type == Marker.SPHERE for m in spheres)
    assert all(m.type == Marker.TEXT_VIEW_FACING for m in texts)
    assert edges[0].type == Marker.LINE_LIST
    assert {m.header.frame_id for m in arr.markers} == {"map"}
    assert [m.id for m in spheres] == list(range(grid.n))
    assert [m.text for m in texts] == [str(v) for v in range(grid.n)]


def test_positions_match_graph(grid):
    arr = build_marker_array(grid, [0.0] * grid.n)
    s0 = by_ns(arr, "vertices")[0]
    assert (s0.pose.position.x, s0.pose.position.y) == pytest.approx((1.425, 24.375))
    t1 = by_ns(arr, "vertex_ids")[1]
    assert (t1.pose.position.x, t1.pose.position.y) == pytest.approx((1.425, 18.675))


def test_edges_once_each(grid, example):
    # grid: 40 undirected edges -> 80 points
    assert len(by_ns(build_marker_array(grid, [0.0] * grid.n), "edges")[0].points) == 80
    # example has multi-edges (8-12, 14-16 twice): merged into 34 distinct pairs
    assert len(undirected_edges(example)) == 34
    e = by_ns(build_marker_array(example, [0.0] * example.n), "edges")[0]
    assert len(e.points) == 68


def test_colour_scale(grid):
    idl = [0.0] * grid.n
    idl[3], idl[7] = 50.0, 100.0
    spheres = by_ns(build_marker_array(grid, idl), "vertices")
    assert (spheres[0].color.r, spheres[0].color.g) == (0.0, 1.0)      # fresh: green
    assert (spheres[7].color.r, spheres[7].color.g) == (1.0, 0.0)      # max: red
    assert spheres[3].color.r == pytest.approx(0.5)
    assert spheres[3].color.g == pytest.approx(0.5)
    # all zero -> all green, no division by zero
    assert all(m.color.g == 1.0 for m in by_ns(build_marker_array(grid, [0.0] * grid.n),
                                               "vertices"))
    c = idleness_color(5.0, 0.0)
    assert (c.r, c.g) == (0.0, 1.0)


def test_wrong_length_rejected(grid):
    with pytest.raises(ValueError, match="25 vertices"):
        build_marker_array(grid, [0.0] * 3)
