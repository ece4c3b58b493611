"""Unit tests of spqrel_nav_lite's pure logic: geometry, planner, controller, particle filter,
obstacle memory (no ROS master)."""
import math
import os
import subprocess

import numpy as np
import pytest

from spqrel_nav_lite.mapio import OccupancyMap, load_map
from spqrel_nav_lite import grid_search
from spqrel_nav_lite.controller import ControllerParams, compute_command, front_clearance
from spqrel_nav_lite.geometry import PoseHistory, compose, inverse, normalize_angle, relative
from spqrel_nav_lite.obstacles import ObstacleMemory, scan_points, to_world
from spqrel_nav_lite.particle_filter import LikelihoodField, ParticleFilter, first_in_bins
from spqrel_nav_lite.planner import GlobalPlanner, PlanningError, path_blocked, path_length

from nav_common import fake_scan

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def room(w=10.0, h=6.0, res=0.05, wall_x=None, gap=None):
    """A walled rectangle; optional vertical wall at wall_x with a gap (y0, y1)."""
    W, H = int(w / res), int(h / res)
    d = np.zeros((H, W), dtype=np.int8)
    d[:2, :] = d[-2:, :] = 100
    d[:, :2] = d[:, -2:] = 100
    if wall_x is not None:
        i = int(wall_x / res)
        d[:, i:i + 2] = 100
        if gap is not None:
            d[int(gap[0] / res):int(gap[1] / res), i:i + 2] = 0
    return OccupancyMap(d, res)


# -- geometry ------------------------------------------------------------------------------------
def test_compose_inverse_roundtrip():
    a, b = (1.0, 2.0, 0.7), (-0.5, 0.3, -2.0)
    c = compose(a, b)
    back = relative(a, c)
    assert np.allclose(back[:2], b[:2]) and abs(normalize_angle(back[2] - b[2])) < 1e-9
    ident = compose(a, inverse(a))
    assert np.allclose(ident, (0, 0, 0), atol=1e-12)


def test_pose_history_interpolates_and_clamps():
    h = PoseHistory(horizon=10)
    h.add(0.0, (0.0, 0.0, 0.0))
    h.add(1.0, (1.0, 2.0, 0.5))
    assert np.allclose(h.at(0.5), (0.5, 1.0, 0.25))
    assert h.at(5.0) == (1.0, 2.0, 0.5) and h.at(-1.0) == (0.0, 0.0, 0.0)
    # at a stored stamp, the stored pose itself (no interpolation rounding)
    rng = np.random.default_rng(5)
    for i in range(11, 200):
        pose = (rng.uniform(-50.0, 50.0), rng.uniform(-50.0, 50.0), rng.uniform(-3.0, 3.0))
        h.add(i * 0.1, pose)
        assert h.at(i * 0.1) is pose and h.at(i * 0.1) == h.latest()[1]


def test_odom_correction_recovers_truth():
    """map->odom = truth o odom^-1, composed with odom again, gives the truth (what
    fake_localization publishes and move_base relies on)."""
    truth, odom = (3.0, 4.0, 1.0), (0.7, -0.2, 0.4)
    corr = compose(truth, inverse(odom))
    assert np.allclose(compose(corr, odom), truth)


# -- planner -----------------------------------------------------------------------------------
def test_planner_goes_through_the_gap():
    m = room(wall_x=5.0, gap=(4.0, 5.5))
    p = GlobalPlanner(m, resolution=0.1)
    path = p.plan((2.0, 1.0), (8.0, 1.0))
    assert np.hypot(*(path[-1] - (8.0, 1.0))) < 1e-9
    # it must pass through the gap: some point near x=5 with y in the gap
    near_wall = path[np.abs(path[:, 0] - 5.05) < 0.15]
    assert len(near_wall) and np.all((near_wall[:, 1] > 4.0) & (near_wall[:, 1] < 5.5))
    # never closer than the robot radius to a wall
    assert min(m.clearance_at(x, y) for x, y in path) >= 0.225 - 0.05
    assert path_length(path) > 6.0 + 2 * 2.0     # detour through the gap


def test_planner_keeps_away_from_walls_when_it_can():
    m = room(w=10, h=4)
    p = GlobalPlanner(m, resolution=0.1)
    path = p.plan((1.0, 0.6), (9.0, 0.6))
    mid = path[len(path) // 2]
    assert mid[1] > 0.9      # soft inflation cost pulls the path off the wall


def test_planner_bad_goals():
    m = room(wall_x=5.0)     # no gap: the right half is unreachable
    p = GlobalPlanner(m)
    with pytest.raises(PlanningError, match="outside the map"):
        p.plan((2.0, 2.0), (20.0, 2.0))
    with pytest.raises(PlanningError, match="inside an obstacle"):
        p.plan((2.0, 2.0), (5.06, 2.0))
    with pytest.raises(PlanningError, match="no path"):
        p.plan((2.0, 2.0), (8.0, 2.0))


def test_planner_goal_near_wall_snaps_within_tolerance():
    m = room()
    p = GlobalPlanner(m)
    path = p.plan((5.0, 3.0), (5.0, 0.2))        # free cell but within the robot radius
    assert math.hypot(path[-1][0] - 5.0, path[-1][1] - 0.2) <= 0.4


def test_planner_temporary_obstacle_blocks_and_clears():
    m = room(w=10, h=2.0)                         # a 1.8 m corridor
    p = GlobalPlanner(m)
    base = p.plan((1.0, 1.0), (9.0, 1.0))
    wall = np.array([[5.0, y] for y in np.arange(0.1, 1.95, 0.05)])
    assert p.set_obstacles(wall)
    with pytest.raises(PlanningError, match="no path"):
        p.plan((1.0, 1.0), (9.0, 1.0))
    assert path_blocked(base, wall, 0.225) is not None
    assert p.clear_obstacles()
    assert len(p.plan((1.0, 1.0), (9.0, 1.0))) == len(base)


def test_planner_caches_obstacle_free_navigation_functions():
    m = room(w=10, h=2.0)
    p = GlobalPlanner(m)
    a = p.plan((1.0, 1.0), (9.0, 1.0))
    p.plan((1.0, 1.0), (5.0, 1.0))
    assert p.searches == 2
    b = p.plan((1.5, 1.0), (9.0, 1.0))           # goal seen before: no new search
    assert p.searches == 2 and np.allclose(a[-1], b[-1])
    # temporary obstacles: never served from the cache, and the path goes around them
    blob = np.array([[5.0, 1.0]])
    p.set_obstacles(blob)
    c = p.plan((1.0, 1.0), (9.0, 1.0))
    assert p.searches == 3 and path_blocked(c, blob, 0.225) is None
    p.clear_obstacles()
    p.plan((1.0, 1.0), (9.0, 1.0))
    assert p.searches == 3                        # back on the cached obstacle-free field
    # an obstacle away from the obstacle-free optimum changes nothing: no search, same path
    p.set_obstacles(np.array([[5.0, 8.0 / 5.0 + 0.3]]))
    assert p._obstacles.any()
    d = p.plan((1.0, 1.0), (9.0, 1.0))
    assert p.searches == 3 and np.allclose(d, a)
    # the cache is bounded in bytes: 0 disables it
    q = GlobalPlanner(m, cache_bytes=0)
    q.plan((1.0, 1.0), (9.0, 1.0))
    q.plan((1.0, 1.0), (5.0, 1.0))
    q.plan((1.0, 1.0), (9.0, 1.0))
    assert q.searches == 3
    one = GlobalPlanner(m, cache_bytes=q.w * q.h * 8)   # room for exactly one field
    for goal in ((9.0, 1.0), (5.0, 1.0), (9.0, 1.0)):
        one.plan((1.0, 1.0), goal)
    assert one.searches == 3 and len(one._cache) == 1


def test_planner_on_shipped_map_all_vertices_reachable():
    from patrolling_sim.model.graph import PatrolGraph
    m = load_map(os.path.join(ROOT, "maps", "cumberland", "cumberland.yaml"))
    g = PatrolGraph.load(os.path.join(ROOT, "maps", "cumberland", "cumberland.graph"))
    p = GlobalPlanner(m)
    for v in range(1, g.n):
        path = p.plan(g.pos[v], g.pos[0])
        assert path_length(path) >= math.dist(g.pos[v], g.pos[0]) - 0.4


# -- controller -----------------------------------------------------------------------------
def straight_path(x0=0.0, x1=10.0):
    return np.column_stack([np.arange(x0, x1 + 1e-9, 0.1),
                            np.zeros(int(round((x1 - x0) / 0.1)) + 1)])


def simulate(path, pose, points_world=np.zeros((0, 2)), steps=400, dt=0.1, p=None):
    p = p or ControllerParams()
    v = w = 0.0
    idx = 0
    trace = []
    for _ in range(steps):
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rel = points_world - pose[:2]
        pts = np.column_stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]])
        cmd = compute_command(pose, v, w, path, idx, pts, dt, p)
        # accelerate within acc_lim_x (a start may jump to min_vel_x); braking may be harder
        assert cmd.v - v <= max(p.acc_lim_x * dt, p.min_vel_x) + 1e-9
        assert abs(cmd.v) <= p.max_vel_x + 1e-9 and abs(cmd.w) <= p.max_rot_vel + 1e-9
        v, w, idx = cmd.v, cmd.w, cmd.index
        trace.append((tuple(pose), cmd))
        if cmd.done:
            break
        pose = np.array([pose[0] + v * dt * math.cos(pose[2]), pose[1] + v * dt * math.sin(pose[2]),
                         normalize_angle(pose[2] + w * dt)])
    return pose, trace


def test_controller_reaches_goal_with_limits():
    pose, trace = simulate(straight_path(), np.array([0.0, 0.3, 0.5]))
    assert trace[-1][1].done
    assert math.hypot(pose[0] - 10.0, pose[1]) <= 0.4
    assert max(t[1].v for t in trace) > 0.9       # reaches cruise speed
    assert len(trace) < 200                        # ~10 m at <= 1 m/s with ramps


def test_controller_turns_in_place_when_facing_away():
    _, trace = simulate(straight_path(), np.array([0.0, 0.0, math.pi]), steps=5)
    assert all(abs(c.v) < 0.06 for _, c in trace) and abs(trace[-1][1].w) > 0.1


def test_controller_stops_before_an_unmapped_obstacle():
    wall = np.array([[4.0, y] for y in np.arange(-1.0, 1.01, 0.05)])
    pose, trace = simulate(straight_path(), np.array([0.0, 0.0, 0.0]), wall, steps=300)
    assert not trace[-1][1].done
    assert any(c.blocked for _, c in trace)
    assert pose[0] < 4.0 - 0.225                  # never touched it


def test_front_clearance_straight_and_empty():
    assert front_clearance(np.zeros((0, 2)), 1.0, 0.0, 0.3, 2.0) == 2.0
    d = front_clearance(np.array([[1.5, 0.0]]), 1.0, 0.0, 0.3, 3.0)
    assert 1.0 <= d <= 1.25


# -- particle filter --------------------------------------------------------------------------
def asym_room():
    m = room(w=8, h=5, wall_x=5.0, gap=(0.1, 1.5))
    d = m.data.copy()
    d[60:64, 20:60] = 100                    # a bar that breaks symmetries
    return OccupancyMap(d, m.resolution)


def _first_in_bins_by_rows(p):
    """The reference: unique rows of the bin indices (what resample used before)."""
    bins = np.column_stack([np.floor(p[:, 0] / 0.5), np.floor(p[:, 1] / 0.5),
                            np.floor(p[:, 2] / math.radians(10.0))]).astype(np.int64)
    return np.sort(np.unique(bins, axis=0, return_index=True)[1])


@pytest.mark.parametrize("case", ["cluster", "uniform", "negative", "one bin", "one particle"])
def test_first_in_bins_equals_unique_rows(case):
    rng = np.random.default_rng(7)
    if case == "cluster":
        p = np.column_stack([rng.normal(10, 0.4, 500), rng.normal(5, 0.4, 500),
                             rng.normal(0, 0.3, 500)])
    elif case == "uniform":           # global localisation on a large map
        p = np.column_stack([rng.uniform(0, 300, 5000), rng.uniform(0, 200, 5000),
                             rng.uniform(-math.pi, math.pi, 5000)])
    elif case == "negative":
        p = np.column_stack([rng.normal(-50, 3, 2000), rng.normal(-20, 3, 2000),
                             rng.uniform(-math.pi, math.pi, 2000)])
    elif case == "one bin":
        p = np.column_stack([rng.uniform(1.01, 1.4, 100), rng.uniform(2.01, 2.4, 100),
                             rng.uniform(0.01, 0.1, 100)])
    else:
        p = np.array([[3.3, -1.2, 2.9]])
    got = first_in_bins(p)
    assert np.array_equal(got, _first_in_bins_by_rows(p))
    if case == "one bin":
        assert list(got) == [0]


def test_kld_limit_bounds():
    field = LikelihoodField(room())
    pf = ParticleFilter(field, 100, 500)
    assert pf.kld_limit(1) == 100
    assert pf.kld_limit(2) == 100
    assert pf.kld_limit(1000) == 500
    assert pf.kld_limit(20) < pf.kld_limit(60)


def test_particle_filter_converges_from_offset():
    m = asym_room()
    field = LikelihoodField(m)
    rng = np.random.default_rng(3)
    pf = ParticleFilter(field, rng=rng)
    truth = np.array([2.0, 2.0, 0.3])
    pf.init_gaussian((2.4, 1.7, 0.6))            # 0.5 m / 0.3 rad off
    angles = np.linspace(-2.35, 2.35, 30)
    odom = (0.0, 0.0, 0.0)
    for k in range(25):
        # drive a small loop; odometry is exact here, the motion model adds the noise
        step = (0.2, 0.0, 0.15 if k % 10 < 5 else -0.15)
        new_truth = np.array(compose(tuple(truth), step))
        if m.clearance_at(*new_truth[:2]) < 0.3:
            step = (0.0, 0.0, 0.6)
            new_truth = np.array(compose(tuple(truth), step))
        new_odom = compose(odom, step)
        pf.predict(odom, new_odom)
        odom, truth = new_odom, new_truth
        pf.update(fake_scan(m, truth, angles), angles)
        pf.resample()
    est, cov = pf.estimate()
    assert math.hypot(est[0] - truth[0], est[1] - truth[1]) < 0.2
    assert abs(normalize_angle(est[2] - truth[2])) < 0.15
    assert 100 <= len(pf.particles) <= 500


def test_motion_model_spread_grows_with_alpha():
    field = LikelihoodField(room())
    spreads = []
    for alpha in (0.01, 0.2):
        pf = ParticleFilter(field, alphas=(alpha,) * 4, rng=np.random.default_rng(0))
        pf.init_gaussian((3, 3, 0), 0, 0, 0)
        pf.predict((0, 0, 0), (1.0, 0.0, 0.0))
        assert abs(pf.particles[:, 0].mean() - 4.0) < 0.15
        assert abs(pf.particles[:, 1].mean() - 3.0) < 0.1
        spreads.append(pf.particles[:, 0].std() + pf.particles[:, 1].std())
    assert spreads[1] > 2 * spreads[0]


def test_low_variance_resampling_keeps_heavy_particles():
    field = LikelihoodField(room())
    pf = ParticleFilter(field, 100, 500, rng=np.random.default_rng(1))
    pf.init_uniform()
    pf.weights = np.zeros(len(pf.particles))
    pf.weights[7] = 1.0
    keep = pf.particles[7].copy()
    pf.resample()
    assert np.allclose(pf.particles, keep) and len(pf.particles) == 100
    assert field.is_free(pf.particles[:, 0], pf.particles[:, 1]).all()


# -- obstacles ---------------------------------------------------------------------------------
def test_scan_points_and_memory_expiry():
    pts, r, a = scan_points([1.0, np.inf, 25.0, 2.0], -0.5, 0.5, 0.05, 20.0, laser_x=0.15)
    assert len(pts) == 2 and np.allclose(pts[0], (0.15 + math.cos(-0.5), math.sin(-0.5)))
    w = to_world(pts, (1.0, 1.0, math.pi / 2))
    assert np.allclose(w[0], (1.0 - math.sin(-0.5), 1.0 + 0.15 + math.cos(-0.5)))
    mem = ObstacleMemory(cell=0.1, timeout=2.0)
    mem.add(np.array([[1.0, 1.0], [1.01, 1.02], [3.0, 3.0]]), now=0.0)
    assert len(mem) == 2
    mem.add(np.array([[3.0, 3.0]]), now=1.5)
    mem.expire(2.5)
    assert len(mem) == 1 and np.allclose(mem.points()[0], (3.05, 3.05))
    # a later beam through the cell to a farther hit clears it
    assert mem.clear_seen_through((0.0, 0.0), np.array([[6.0, 6.0]]), now=2.6)
    assert len(mem) == 0


def test_memory_clear_seen_through_matches_brute_force():
    """The bearing search finds, for every cell, the same nearest beam as comparing every
    cell with every beam (wrap-around at +-pi included)."""
    def brute(cells, hits, now, margin=0.3, cell=0.1):
        out = set()
        for (i, j), seen in cells.items():
            cx, cy = (i + 0.5) * cell, (j + 0.5) * cell
            ac, dc = math.atan2(cy, cx), math.hypot(cx, cy)
            best = min(range(len(hits)), key=lambda k: abs(
                (ac - math.atan2(hits[k][1], hits[k][0]) + math.pi) % (2 * math.pi) - math.pi))
            d = abs((ac - math.atan2(hits[best][1], hits[best][0]) + math.pi) % (2 * math.pi)
                    - math.pi)
            if d < math.radians(2.0) and dc < math.hypot(*hits[best]) - margin and now > seen:
                out.add((i, j))
        return out

    rng = np.random.default_rng(7)
    for _ in range(60):
        mem = ObstacleMemory(cell=0.1)
        mem.add(rng.uniform(-4, 4, size=(int(rng.integers(1, 80)), 2)), now=0.0)
        ang = rng.uniform(-math.pi, math.pi, int(rng.integers(1, 120)))
        ang[:2] = (math.pi - 1e-3, -math.pi + 1e-3)           # beams either side of the cut
        r = rng.uniform(0.2, 6.0, len(ang))
        hits = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
        before = dict(mem._cells)
        mem.clear_seen_through((0.0, 0.0), hits, now=1.0)
        assert set(before) - set(mem._cells) == brute(before, hits, 1.0)


# -- command line -----------------------------------------------------------------------------
def test_map_server_bad_yaml_one_line_error(tmp_path):
    exe = os.path.join(ROOT, "src", "spqrel_nav_lite", "nodes", "map_server")
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    for args in ([str(bad)], [str(tmp_path / "none.yaml")], []):
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [os.path.join(ROOT, "src", p, "src") for p in ("patrolling_sim", "spqrel_nav_lite")]
            + [os.environ.get("PYTHONPATH", "")]))
        proc = subprocess.run(["/usr/bin/python3", exe] + args, capture_output=True, text=True,
                              env=env, timeout=60)
        assert proc.returncode != 0
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("map_server: error:"), proc.stderr
        if args:
            assert os.path.basename(args[0]) in lines[0]


def test_controller_brakes_harder_for_unmapped_points():
    """The same point ahead: as a static map obstacle the robot may keep more speed than as
    an unexplained (possibly moving) one, which also stops it earlier."""
    p = ControllerParams()
    path = straight_path()
    pts = np.array([[1.6, 0.0]])
    static = compute_command((0.0, 0.0, 0.0), 0.8, 0.0, path, 0, pts, 0.1, p)
    dynamic = compute_command((0.0, 0.0, 0.0), 0.8, 0.0, path, 0, pts, 0.1, p, pts)
    assert dynamic.v < static.v
    close = np.array([[0.6, 0.0]])
    assert not compute_command((0.0, 0.0, 0.0), 0.8, 0.0, path, 0, close, 0.1, p).blocked
    assert compute_command((0.0, 0.0, 0.0), 0.8, 0.0, path, 0, close, 0.1, p, close).blocked


def test_controller_stops_for_a_robot_coming_head_on_in_time():
    """Two robots at 0.75 m/s, 0.725 m between their surfaces (the other robot's near side
    seen 0.95 m from this centre, half a second from contact if both drive on): the other
    closes the gap as fast as this one, so this one must stop now. The old rule (one
    reaction distance, the plain safety disc) let both drive on, and they stopped 1-6 cm
    apart (head_on_stage2d.test, touching after one late control cycle under load)."""
    p = ControllerParams()
    path = straight_path()
    other = np.array([[0.95, y] for y in (-0.1, 0.0, 0.1)])
    cmd = compute_command((0.0, 0.0, 0.0), 0.75, 0.0, path, 0, other, 0.1, p, other)
    assert cmd.blocked and cmd.v == 0.0
    # the same point as a wall (mapped): slowing down, not an emergency stop
    assert not compute_command((0.0, 0.0, 0.0), 0.75, 0.0, path, 0, other, 0.1, p).blocked
    # far enough away: not blocked, only slowed
    far = other + [1.5, 0.0]
    assert not compute_command((0.0, 0.0, 0.0), 0.75, 0.0, path, 0, far, 0.1, p, far).blocked


def shipped_planner(name, seed, search="window"):
    """(planner on the shipped map ``name``, 0.2 m around temporary obstacles, a seeded
    generator, the open cells as (j, i) rows) for the randomised planner tests; ``search``:
    the planner's ``obstacle_search`` (the window and box tests below test scipy's searches,
    the planner's fallback without the C++ library)."""
    p = GlobalPlanner(load_map(os.path.join(ROOT, "maps", name, f"{name}.yaml")),
                      obstacle_margin=0.2, obstacle_search=search)
    return p, np.random.default_rng(seed), np.argwhere(~p.lethal)


def random_free_plan(p, rng, free):
    """(start, goal, goal cell (i, j), obstacle-free path) between two random open cells of
    ``free`` (rows (j, i)), the planner's temporary obstacles cleared first; None when the
    two cells are not connected."""
    (aj, ai), (bj, bi) = free[rng.integers(len(free), size=2)]
    start, goal = p.cell_center(ai, aj), p.cell_center(bi, bj)
    p.clear_obstacles()
    try:
        return start, goal, (bi, bj), p.plan(start, goal)
    except PlanningError:
        return None


def test_astar_library_is_built_with_the_workspace():
    """Once catkin built the workspace (as `make test` does), the planner must find the C++
    A* and use it by default; without a build (`make unit`) it falls back to scipy."""
    if not os.path.isdir(os.path.join(ROOT, "devel", "lib")):
        pytest.skip("workspace not built (no devel/lib): the planner uses scipy's searches")
    assert grid_search.load() is not None
    p = GlobalPlanner(room(w=4, h=2.0))
    assert p.astar and p.search_label == "A* (C++)"
    assert not GlobalPlanner(room(w=4, h=2.0), obstacle_search="window").astar
    with pytest.raises(ValueError, match="obstacle_search"):
        GlobalPlanner(room(w=4, h=2.0), obstacle_search="bfs")


needs_astar = pytest.mark.skipif(
    grid_search.load() is None,
    reason="the C++ A* is not built (run catkin_make): test_astar_library_is_built_... "
           "fails in a built workspace")


@needs_astar
@pytest.mark.parametrize("name", ["grid", "cumberland", "broughton"])
def test_planner_astar_around_robots_is_exact(name):
    """With the C++ A* the searches around temporary obstacles (robots on or near the
    obstacle-free optimum, or on the goal vertex itself, which moves the goal) cost what a
    whole-map Dijkstra with the same obstacles gives, avoid the obstacles, and expand far
    fewer cells than the grid has; a robot beside the path steps back onto it, one further
    off is searched again."""
    p, rng, free = shipped_planner(name, 23, search="astar")
    assert p.astar
    checked = searched = moved = band = 0
    for _ in range(40):
        drawn = random_free_plan(p, rng, free)
        if drawn is None:
            continue
        start, goal, (bi, bj), base = drawn
        pts = base[rng.integers(len(base), size=rng.integers(1, 4))] + \
            rng.normal(0.0, 0.3, (1, 2))
        on_goal = rng.random() < 0.3
        if on_goal:
            pts = np.vstack([pts, np.array(goal) + rng.normal(0.0, 0.1, (1, 2))])
        p.set_obstacles(pts)
        si, sj = p.cell(*start)
        if p.blocked_mask()[sj, si]:
            continue
        before, expanded = p.astar_searches, p.astar_expanded
        try:
            path = p.plan(start, goal)
            cost, g = p.path_cost(start), p._field[0]
        except PlanningError:
            cost, g = math.inf, None
        if g is None:
            continue
        ref = whole_map_cost(p, g, si, sj)
        assert cost == pytest.approx(ref, rel=1e-5), (name, start, goal, pts)
        assert path_blocked(path[:-1], pts, p.robot_radius) is None
        checked += 1
        if p.astar_searches > before:
            assert p._field[4] == "astar"
            assert p.astar_expanded - expanded < p.w * p.h // 4
            moved += g != bj * p.w + bi
            # a cell beside the path is in the field's band: it steps back onto the path
            # (at least the exact cost); from a cell outside the band
            # the next plan searches again, exactly
            for i, j in ((si + 1, sj), (si, sj - 1), (si - 2, sj), (si, sj + 2)):
                if p._field[4] != "astar":
                    break               # a search from outside the band used the box
                if not p.in_grid(i, j) or p.blocked_mask()[j, i]:
                    continue
                n, here = p.searches, p.cell_center(i, j)
                inside = bool(np.isfinite(p._field[1][j * p.w + i]))
                walk = p.plan(here, goal)
                assert (p.searches == n) if inside else (p.searches > n)
                exact = whole_map_cost(p, p._field[0], i, j)
                assert path_blocked(walk[:-1], pts, p.robot_radius) is None
                if inside:
                    # (exact >= the path cell's cost - one step, so at most two steps more)
                    step = math.sqrt(2) * p.res * p.cost.max()
                    assert exact * (1 - 1e-5) <= p.path_cost(here) <= exact + 2 * step + 1e-5
                    band += 1
                else:
                    assert p.path_cost(here) == pytest.approx(exact, rel=1e-5)
            searched += 1
    assert checked >= 10 and searched >= 3 and band >= 3, (checked, searched, moved, band)


@needs_astar
def test_planner_astar_leaves_the_free_path_as_early_as_dijkstra():
    """Among equally cheap ways around a robot standing on the obstacle-free path, the A*'s
    path must leave that path as early as the path of a Dijkstra field from the goal does
    (the window and box searches: each cell linked to its neighbour nearest the goal), not
    follow it up to the robot and swerve at the last moment (A*'s own tie-breaking: on grid
    0.93 m against 0.64 m from the start on average, and a third more stops in front of other
    robots in the 12-robot runs, docs/navigation.md)."""
    from scipy.sparse.csgraph import dijkstra
    p, rng, free = shipped_planner("grid", 5, search="astar")
    ring = 0.2 * np.column_stack([np.cos(np.arange(12) * math.pi / 6),
                                  np.sin(np.arange(12) * math.pi / 6)])

    def leaves(path, base):
        """Arc length (m) at which ``path`` is first more than 1.5 cells off ``base``."""
        off = np.sqrt(((path[:, None, :] - base[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
        far = off > 1.5 * p.res
        return arc[np.argmax(far)] if far.any() else arc[-1]

    astar, ref = [], []
    while len(astar) < 25:
        drawn = random_free_plan(p, rng, free)
        if drawn is None:
            continue
        start, goal, (bi, bj), base = drawn
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(base, axis=0).T))])
        if arc[-1] < 4.0:
            continue
        p.set_obstacles(base[np.searchsorted(arc, rng.uniform(1.2, 3.0))] +
                        rng.normal(0.0, 0.15, 2) + ring)
        n = p.astar_searches
        try:
            path = p.plan(start, goal)
        except PlanningError:
            continue
        if p.astar_searches == n or p._field[0] != bj * p.w + bi:
            continue                    # the box settled it, or the goal moved
        si, sj = p.cell(*start)
        _, pred = dijkstra(p._csgraph(), directed=True, indices=p._field[0],
                           return_predecessors=True)
        cells = [sj * p.w + si]
        while pred[cells[-1]] >= 0:
            cells.append(pred[cells[-1]])
        cells = np.array(cells)
        walk = np.column_stack([p.origin[0] + (cells % p.w + 0.5) * p.res,
                                p.origin[1] + (cells // p.w + 0.5) * p.res])
        astar.append(leaves(path[:-1], base))
        ref.append(leaves(walk, base))
    assert np.mean(astar) <= np.mean(ref) + 0.05, (np.mean(astar), np.mean(ref))


def whole_map_cost(p, g, si, sj):
    """Cost from cell (si, sj) to goal cell index ``g`` by a Dijkstra over the whole map with
    ``p``'s temporary obstacles: the reference of the windowed and boxed searches."""
    from scipy.sparse.csgraph import dijkstra
    return dijkstra(p._csgraph(), directed=True, indices=g)[sj * p.w + si]


@pytest.mark.parametrize("name", ["grid", "cumberland"])
def test_planner_windowed_search_with_obstacles_is_exact(name):
    """The search around temporary obstacles runs in a window; its path cost must equal a
    whole-map Dijkstra with the same obstacles (from the start and goal cells the plan used)."""
    p, rng, free = shipped_planner(name, 7)
    checked = 0
    for _ in range(40):
        (aj, ai), (bj, bi) = free[rng.integers(len(free), size=2)]
        start, goal = p.cell_center(ai, aj), p.cell_center(bi, bj)
        try:
            base = p.plan(start, goal)
        except PlanningError:
            continue
        # one to three robots standing on or near the obstacle-free optimum
        pts = base[rng.integers(len(base), size=rng.integers(1, 4))] + \
            rng.normal(0.0, 0.3, (3, 2))[:1]
        p.set_obstacles(pts)
        si, sj = p.cell(*start)
        if p.blocked_mask()[sj, si]:
            p.clear_obstacles()
            continue
        try:
            path = p.plan(start, goal)
            cost = p.path_cost(start)
            g = p._field[0]
        except PlanningError:
            cost, g = math.inf, None
        if g is not None:
            ref = whole_map_cost(p, g, si, sj)
            assert cost == pytest.approx(ref, rel=1e-5), (start, goal, pts)
            # (the last point is the goal itself, which may lie beside a robot)
            assert path_blocked(path[:-1], pts, p.robot_radius) is None
            checked += 1
        p.clear_obstacles()
    assert checked >= 12 and p.window_searches >= 5, (checked, p.window_searches)


@pytest.mark.parametrize("name", ["grid", "cumberland"])
def test_planner_goal_taken_by_a_robot_is_exact_and_keeps_the_cache(name):
    """A robot standing on the goal vertex moves the goal to the nearest open cell: the plan
    there must cost what a whole-map Dijkstra with the same obstacles gives, and the moved
    cell (a new one for every robot standing nearby) must not cost a whole-map search nor
    enter the navigation-function cache; the vertex's own obstacle-free function does."""
    p, rng, free = shipped_planner(name, 11)
    checked = 0
    for _ in range(80):
        (aj, ai), (bj, bi) = free[rng.integers(len(free), size=2)]
        start, goal = p.cell_center(ai, aj), p.cell_center(bi, bj)
        # a robot on the goal, slightly off its centre
        p.set_obstacles(np.array(goal) + rng.normal(0.0, 0.1, (1, 2)))
        si, sj = p.cell(*start)
        if p.blocked_mask()[sj, si]:
            continue
        p._cache._d.clear()
        before = p.searches
        try:
            path = p.plan(start, goal)
        except PlanningError:
            continue
        g = p._field[0]
        assert g != bj * p.w + bi                       # the goal was moved off its cell
        assert math.hypot(path[-1][0] - goal[0], path[-1][1] - goal[1]) <= 0.4 + p.res
        ref = whole_map_cost(p, g, si, sj)
        assert p.path_cost(start) == pytest.approx(ref, rel=1e-5), (start, goal)
        assert list(p._cache._d) == [bj * p.w + bi]      # only the vertex's own function
        assert not p._field[3]                          # searched with the obstacles
        assert p.searches - before >= 2                 # vertex function + window search(es)
        checked += 1
    assert checked >= 12, checked


def test_window_graph_is_the_cut_of_the_free_graph():
    """The window's graph holds exactly the obstacle-free graph's edges between window cells
    that are not blocked, with the same weights (placeholders are infinite self-loops)."""
    from spqrel_nav_lite.planner_grid import PlannerGrid, window_graph
    m = load_map(os.path.join(ROOT, "maps", "cumberland", "cumberland.yaml"))
    grid = PlannerGrid(m)
    rng = np.random.default_rng(5)
    for _ in range(12):
        i0, j0 = rng.integers(0, grid.w - 30), rng.integers(0, grid.h - 30)
        i1, j1 = i0 + rng.integers(1, 30), j0 + rng.integers(1, 30)
        if rng.random() < 0.3:              # windows on the grid's border
            i0, i1, j0, j1 = 0, i1 - i0, grid.h - (j1 - j0), grid.h
        blocked = rng.random((grid.h, grid.w)) < 0.05
        g = window_graph(grid, blocked, i0, j0, i1, j1)
        rows = np.arange(g.shape[0]).repeat(np.diff(g.indptr))
        fin = np.isfinite(g.data)
        assert np.all(g.indices[~fin] == rows[~fin]) and np.all(g.data[fin] > 0)
        cells = (np.arange(j0, j1)[:, None] * grid.w + np.arange(i0, i1)[None, :]).ravel()
        ref = grid.free_graph[cells][:, cells].toarray()
        keep = ~blocked.ravel()[cells]
        ref[~keep, :] = 0
        ref[:, ~keep] = 0
        got = np.zeros_like(ref)
        got[rows[fin], g.indices[fin]] = g.data[fin]
        assert np.array_equal(got, ref)


@pytest.mark.parametrize("name", ["cumberland", "broughton"])
def test_planner_box_search_around_nearby_robots_is_exact(name):
    """Robots a few metres ahead of a robot far from its goal: the plan comes from the small
    box around them (not a window spanning start and goal) and costs what a whole-map
    Dijkstra with the same obstacles gives."""
    p, rng, free = shipped_planner(name, 13)
    boxes = 0
    for _ in range(60):
        (aj, ai), (bj, bj_i) = free[rng.integers(len(free), size=2)]
        start, goal = p.cell_center(ai, aj), p.cell_center(bj_i, bj)
        p.clear_obstacles()
        try:
            base = p.plan(start, goal)
        except PlanningError:
            continue
        if path_length(base) < 15.0:
            continue
        k = rng.integers(10, 25)
        p.set_obstacles(base[k:k + 1] + rng.normal(0.0, 0.2, (2, 2)))
        si, sj = p.cell(*start)
        if p.blocked_mask()[sj, si]:
            continue
        try:
            p.plan(start, goal)
            cost = p.path_cost(start)
        except PlanningError:
            cost = math.inf
        ref = whole_map_cost(p, bj * p.w + bj_i, si, sj)
        assert cost == pytest.approx(ref, rel=1e-5), (start, goal)
        box = p._field[4]       # None: the obstacle-free path was clear, or a whole-map search
        boxes += box is not None and (box[2] - box[0]) * p.res < 8.0 and \
            (box[3] - box[1]) * p.res < 8.0
    assert boxes >= 10, boxes


def test_planner_robot_boxed_in_has_no_path_without_a_whole_map_search():
    m = room(w=10, h=6.0)
    p = GlobalPlanner(m)
    p.plan((2.0, 3.0), (9.0, 3.0))
    a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    p.set_obstacles(np.column_stack([2.0 + 0.8 * np.cos(a), 3.0 + 0.8 * np.sin(a)]))
    before = p.searches
    with pytest.raises(PlanningError, match="no path"):
        p.plan((2.0, 3.0), (9.0, 3.0))
    assert p.searches - before == 1 and p._field[4] is not None


@pytest.mark.parametrize("name", ["cumberland", "broughton"])
def test_planner_goal_taken_near_the_robot_is_searched_in_the_box(name):
    """A robot standing on the goal vertex 1-3 m ahead (as the laser sees it): the moved goal
    is reached inside the small box, exactly as a whole-map Dijkstra with the obstacles."""
    p, rng, free = shipped_planner(name, 17)
    boxes = 0
    for _ in range(80):
        bj, bi = free[rng.integers(len(free))]
        goal = p.cell_center(bi, bj)
        a, r = rng.uniform(0, 2 * np.pi), rng.uniform(1.0, 3.0)
        start = (goal[0] + r * np.cos(a), goal[1] + r * np.sin(a))
        si, sj = p.cell(*start)
        if not p.in_grid(si, sj) or p.lethal[sj, si]:
            continue
        p.set_obstacles(np.array(goal) + rng.normal(0.0, 0.1, (1, 2)))
        if p.blocked_mask()[sj, si]:
            continue
        try:
            p.plan(start, goal)
            cost, g = p.path_cost(start), p._field[0]
        except PlanningError:
            continue
        ref = whole_map_cost(p, g, si, sj)
        assert g != bj * p.w + bi and cost == pytest.approx(ref, rel=1e-5), (start, goal)
        box = p._field[4]
        # (a window spans at least 2 m beyond start and goal: 4.1 m or more each way)
        boxes += box is not None and (box[2] - box[0]) * p.res < 4.0 and \
            (box[3] - box[1]) * p.res < 4.0
    assert boxes >= 10, boxes
