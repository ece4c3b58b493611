"""The plan store (spqrel_nav_lite.plan_store): navigation functions written by one planner
grid are read back, identical, by another one on the same cell graph (another process or a
later run), never by a grid on another graph; damaged files are searched again; the store
stays within its bound; the runner hands its folder to every navigation process. No ROS
master needed."""
import os

import numpy as np
import pytest

from spqrel_nav_lite import plan_store
from spqrel_nav_lite.mapio import OccupancyMap
from spqrel_nav_lite.planner import GlobalPlanner
from spqrel_nav_lite.planner_grid import PlannerGrid
from spqrel_nav_lite.shared import SharedMaps


def corridors(wall_end=170):
    """10 m x 6 m room with a wall in the middle, open at both ends."""
    data = np.zeros((120, 200), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    data[59:61, 30:wall_end] = 100
    return OccupancyMap(data, 0.05)


def npy_files(root):
    return sorted(os.path.join(d, f) for d, _, fs in os.walk(root) for f in fs
                  if f.endswith(".npy"))


def test_a_second_grid_reads_the_first_ones_searches(tmp_path):
    m = corridors()
    a = PlannerGrid(m, store_root=str(tmp_path))
    goals = [a.h // 4 * a.w + 10, a.h * 3 // 4 * a.w + a.w - 12, 5 * a.w + 50]
    first = [a.free_navigation_function(g) for g in goals]
    assert all(searched for _, _, searched in first)
    assert a.store.saves == 3 and len(npy_files(tmp_path)) == 3
    b = PlannerGrid(m, store_root=str(tmp_path))          # another process, a later run
    assert b.store.dir == a.store.dir
    for g, (d1, p1, _) in zip(goals, first):
        d2, p2, searched = b.free_navigation_function(g)
        assert not searched
        assert d2.dtype == np.float32 and p2.dtype == np.int32
        assert np.array_equal(d1, d2) and np.array_equal(p1, p2)
        assert not d2.flags.writeable            # mapped read-only: shared pages
    assert b.store.loads == 3 and b.store.saves == 0


def test_plans_with_a_stored_field_equal_plans_without_a_store(tmp_path):
    """Whole plans, with and without temporary obstacles (which read the stored
    obstacle-free field as a bound and as the continuation outside their box)."""
    m = corridors()
    PlannerGrid(m, store_root=str(tmp_path)).free_navigation_function(0)   # unrelated goal
    rng = np.random.default_rng(3)
    free = [(x, y) for x in np.arange(0.5, 9.6, 0.5) for y in np.arange(0.5, 5.6, 0.5)
            if m.clearance_at(x, y) > 0.5]
    pairs = [tuple(free[i] for i in rng.choice(len(free), 2, replace=False)) for _ in range(12)]
    warm = GlobalPlanner(m, obstacle_margin=0.2,
                         grid=PlannerGrid(m, store_root=str(tmp_path)))
    for s, g in pairs:            # fill the store with these goals
        warm.plan(s, g)
    stored = GlobalPlanner(m, obstacle_margin=0.2,
                           grid=PlannerGrid(m, store_root=str(tmp_path)))
    alone = GlobalPlanner(m, obstacle_margin=0.2)
    blob = np.array([[x, y] for x in np.arange(4.0, 4.6, 0.05) for y in np.arange(0.2, 2.0, 0.05)])
    for obstacles in (np.zeros((0, 2)), blob):
        stored.set_obstacles(obstacles)
        alone.set_obstacles(obstacles)
        for s, g in pairs:
            assert np.array_equal(stored.plan(s, g), alone.plan(s, g))
    assert stored.grid.store.loads > 0 and stored.grid.store.saves == 0


def test_another_graph_gets_another_folder(tmp_path):
    m = corridors()
    base = PlannerGrid(m, store_root=str(tmp_path)).store.dir
    assert PlannerGrid(corridors(wall_end=160), store_root=str(tmp_path)).store.dir != base
    assert PlannerGrid(m, robot_radius=0.3, store_root=str(tmp_path)).store.dir != base
    assert PlannerGrid(m, inflation_radius=0.5, store_root=str(tmp_path)).store.dir != base
    assert PlannerGrid(m, resolution=0.15, store_root=str(tmp_path)).store.dir != base
    shifted = OccupancyMap(m.data, 0.05, origin=(1.0, 0.0, 0.0))
    assert PlannerGrid(shifted, store_root=str(tmp_path)).store.dir != base
    assert PlannerGrid(corridors(), store_root=str(tmp_path)).store.dir == base
    with open(os.path.join(base, "grid.txt")) as f:
        assert "robot_radius 0.225" in f.read()


@pytest.mark.parametrize("damage", ["truncate", "empty", "garbage", "shape"])
def test_a_damaged_file_is_searched_again_and_replaced(tmp_path, damage, caplog):
    m = corridors()
    a = PlannerGrid(m, store_root=str(tmp_path))
    d1, p1, _ = a.free_navigation_function(77)
    path = a.store.path(77)
    if damage == "truncate":
        with open(path, "r+b") as f:
            f.truncate(os.path.getsize(path) // 2)
    elif damage == "empty":                      # what a crash can leave on ext4
        open(path, "wb").close()
    elif damage == "garbage":
        with open(path, "wb") as f:
            f.write(b"not a numpy file")
    else:
        np.save(path, np.zeros((2, 10), dtype=np.int32))
    b = PlannerGrid(m, store_root=str(tmp_path))
    d2, p2, searched = b.free_navigation_function(77)
    assert searched and np.array_equal(d1, d2) and np.array_equal(p1, p2)
    assert "plan store" in caplog.text and path in caplog.text
    c = PlannerGrid(m, store_root=str(tmp_path))              # replaced by b's search
    assert not c.free_navigation_function(77)[2]


def test_the_store_stays_within_its_bound_least_recently_used_first(tmp_path):
    m = corridors()
    g0 = PlannerGrid(m)
    per_file = 128 + 8 * g0.w * g0.h
    bound = int(6.5 * per_file)
    grid = PlannerGrid(m, store_root=str(tmp_path), store_bytes=bound)
    assert grid.store.file_bytes == per_file
    for k, g in enumerate(range(100, 106)):
        grid.free_navigation_function(g)
        os.utime(grid.store.path(g), (1000 + k, 1000 + k))    # distinct ages, oldest first
    assert len(npy_files(tmp_path)) == 6
    # a read makes a file recent again: another process reads 101
    other = PlannerGrid(m, store_root=str(tmp_path), store_bytes=bound)
    assert not other.free_navigation_function(101)[2]
    grid.free_navigation_function(106)       # 7 files > 6.5: down to 90 % of the bound
    grid.free_navigation_function(107)
    left = npy_files(tmp_path)
    assert sum(os.path.getsize(p) for p in left) <= bound
    assert [grid.store.path(g) in left for g in range(100, 108)] == \
        [False, True, False, True, True, True, True, True]


def test_a_store_that_cannot_be_written_is_used_read_only(tmp_path, caplog):
    m = corridors()
    blocker = tmp_path / "file"
    blocker.write_text("")
    g = PlannerGrid(m, store_root=str(blocker / "store"))    # below a regular file
    assert not g.store.writable and "cannot write" in caplog.text
    d, p, searched = g.free_navigation_function(50)
    assert searched and np.isfinite(d).any()
    assert not g.free_navigation_function(50)[2]             # still in the memory cache


def test_killed_writers_leave_no_partial_file_that_is_read(tmp_path):
    m = corridors()
    a = PlannerGrid(m, store_root=str(tmp_path))
    tmp = a.store.path(60) + ".999.1.tmp"
    with open(tmp, "wb") as f:
        f.write(b"half")
    os.utime(tmp, (0, 0))                                    # a writer killed long ago
    assert a.free_navigation_function(60)[2]                 # not read: searched
    a.store.limit = 0                                        # force the next save's scan
    a.store.writable = True
    a.free_navigation_function(61)
    assert not os.path.exists(tmp)


def test_shared_maps_pass_the_store_and_count_it(tmp_path):
    m = corridors()
    s1 = SharedMaps(m, cache_bytes=8 << 20, store_root=str(tmp_path))
    s1.planner_grid(0.225, 0.66, 0.1, cache_bytes=1).free_navigation_function(42)
    s2 = SharedMaps(m, cache_bytes=8 << 20, store_root=str(tmp_path))
    s2.planner_grid(0.225, 0.66, 0.1, cache_bytes=1).free_navigation_function(42)
    assert s1.stats()[5:] == (0, 1) and s2.stats()[5:] == (1, 0)
    assert SharedMaps(m).planner_grid(0.225, 0.66, 0.1, cache_bytes=1).store is None


def test_default_root(monkeypatch, tmp_path):
    monkeypatch.delenv("PATROLLING_SIM_PLAN_STORE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert plan_store.default_root() == str(tmp_path / "patrolling_sim" / "plan_store")
    monkeypatch.setenv("PATROLLING_SIM_PLAN_STORE", "none")
    assert plan_store.default_root() is None
    monkeypatch.setenv("PATROLLING_SIM_PLAN_STORE", "")
    assert plan_store.default_root() is None
    monkeypatch.setenv("PATROLLING_SIM_PLAN_STORE", str(tmp_path / "s"))
    assert plan_store.default_root() == str(tmp_path / "s")
