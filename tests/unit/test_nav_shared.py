"""Structures shared by the robots of a nav_host process: SharedMaps (built once, same
objects), the planner grid with its thread-safe navigation-function cache, per-robot planner
state kept apart. No ROS master needed."""
import threading

import numpy as np
import pytest

from spqrel_nav_lite.mapio import OccupancyMap
from spqrel_nav_lite.planner import GlobalPlanner, path_blocked
from spqrel_nav_lite.planner_grid import NavFunctionCache, PlannerGrid
from spqrel_nav_lite.shared import SharedMaps


def corridors():
    """10 m x 6 m room with a wall in the middle, open at both ends."""
    data = np.zeros((120, 200), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[59:61, 30:170] = 100
    return OccupancyMap(data, 0.05)


def test_shared_maps_build_each_structure_once():
    m = corridors()
    s = SharedMaps(m, cache_bytes=8 << 20)
    f1, f2 = s.likelihood_field(1.0), s.likelihood_field(1.0)
    assert f1 is f2 and s.likelihood_field(2.0) is not f1
    assert s.likelihood_field(2.0).max_dist == 2.0
    g1 = s.planner_grid(0.225, 0.66, 0.1, cache_bytes=1)
    g2 = s.planner_grid(0.225, 0.66, 0.1, cache_bytes=1 << 30)
    assert g1 is g2
    # the process's bound wins over the requests'
    assert g1.cache.capacity == (8 << 20) // (g1.w * g1.h * 8)
    assert s.planner_grid(0.3, 0.66, 0.1, cache_bytes=1) is not g1
    assert s.stats()[:2] == (2, 2)


def test_robots_share_searches_but_not_obstacles():
    m = corridors()
    grid = PlannerGrid(m, cache_bytes=64 << 20)
    a = GlobalPlanner(m, obstacle_margin=0.2, grid=grid)
    b = GlobalPlanner(m, obstacle_margin=0.2, grid=grid)
    alone = GlobalPlanner(m, obstacle_margin=0.2)
    start, goal = (1.0, 1.0), (9.0, 5.0)
    pa = a.plan(start, goal)
    assert a.searches == 1
    pb = b.plan((2.0, 1.5), goal)          # same goal, another robot: no search at all
    assert b.searches == 0 and grid.cache.hits >= 1
    assert np.allclose(pb, alone.plan((2.0, 1.5), goal))
    # temporary obstacles are per robot: a's blob changes a's path only
    blob = np.array([[x, y] for x in np.arange(4.0, 6.0, 0.05) for y in np.arange(0.2, 2.9, 0.05)])
    assert a.set_obstacles(blob)
    pa2 = a.plan(start, goal)
    assert b.plan(start, goal).shape == pa.shape and np.allclose(b.plan(start, goal), pa)
    assert path_blocked(pa, blob, 0.225) is not None and path_blocked(pa2, blob, 0.225) is None
    assert not b._obstacles.any()


def test_cache_is_bounded_lru_and_thread_safe():
    c = NavFunctionCache(cells=10, cache_bytes=3 * 10 * 8)
    assert c.capacity == 3
    field = (np.zeros(10, np.float32), np.zeros(10, np.int32))
    for g in range(3):
        c.put(g, field)
    assert c.get(0) is field          # 0 becomes most recent
    c.put(3, field)                   # evicts 1, the least recently used
    assert 1 not in c and 0 in c and len(c) == 3
    errors = []

    def hammer(k):
        try:
            for i in range(2000):
                c.put((k * 7 + i) % 11, field)
                c.get(i % 11)
                assert len(c) <= 3
        except Exception as e:     # pragma: no cover - reported below
            errors.append(e)
    threads = [threading.Thread(target=hammer, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors and len(c) <= 3
    assert NavFunctionCache(cells=10, cache_bytes=0).capacity == 0
    # room for every patrol goal even when the byte bound would hold fewer
    assert NavFunctionCache(cells=10, cache_bytes=3 * 10 * 8, min_entries=7).capacity == 7
    s = SharedMaps(corridors(), cache_bytes=0, cache_goals=5)
    assert s.planner_grid(0.225, 0.66, 0.1, cache_bytes=0).cache.capacity == 5


def test_concurrent_planners_on_one_grid_agree_with_a_private_planner():
    m = corridors()
    grid = PlannerGrid(m, cache_bytes=64 << 20)
    goals = [(9.0, 5.0), (1.0, 5.0), (9.0, 1.0), (5.0, 0.5)]
    starts = [(1.0, 1.0), (8.5, 1.0), (2.0, 4.5), (5.0, 5.5)]
    ref = GlobalPlanner(m, obstacle_margin=0.2, cache_bytes=0)
    expected = {(s, g): ref.plan(s, g) for s in starts for g in goals}
    got, errors = {}, []

    def robot(k):
        p = GlobalPlanner(m, obstacle_margin=0.2, grid=grid)
        try:
            for r in range(3):
                for g in goals[k:] + goals[:k]:
                    s = starts[(k + r) % len(starts)]
                    got[(s, g, k, r)] = p.plan(s, g)
        except Exception as e:     # pragma: no cover - reported below
            errors.append(e)
    threads = [threading.Thread(target=robot, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for (s, g, _, _), path in got.items():
        assert np.allclose(path, expected[(s, g)])
    assert len(grid.cache) == len(goals)
    # each goal searched at most once per racing robot, far fewer than 4 robots x 4 goals x 3
    assert grid.cache.misses <= 4 * len(goals)


@pytest.mark.parametrize("value,err", [
    ("", "non-empty"), ([], "non-empty"), ("robot_0 robot_0", "twice"),
    ("robot_0 9bad", "not a valid namespace"), (42, "non-empty"),
])
def test_nav_host_robot_list_errors(value, err):
    from spqrel_nav_lite.nav_host_node import robot_namespaces
    with pytest.raises(ValueError, match=err):
        robot_namespaces(value)


def test_nav_host_robot_list():
    from spqrel_nav_lite.nav_host_node import robot_namespaces
    assert robot_namespaces("robot_0 /robot_1/ robot_2") == ["robot_0", "robot_1", "robot_2"]
    assert robot_namespaces(["a", "b/c"]) == ["a", "b/c"]
