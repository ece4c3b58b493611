"""Local controller: pure pursuit along the global path for a differential-drive robot, with
acceleration limits, slow-down near obstacles and a swept-corridor collision check against
laser points. Pure functions of the inputs (no ROS)."""
import math
from dataclasses import dataclass

import numpy as np

from .geometry import normalize_angle


@dataclass
class ControllerParams:
    max_vel_x: float = 1.0
    min_vel_x: float = 0.1
    max_rot_vel: float = 1.0
    min_in_place_rotational_vel: float = 0.1
    acc_lim_x: float = 0.5
    acc_lim_th: float = 0.75
    robot_radius: float = 0.225
    lookahead: float = 0.6          # pure-pursuit look-ahead at low speed (m)
    lookahead_gain: float = 0.4     # extra look-ahead per m/s
    rotate_in_place_angle: float = 0.8   # heading error above which the robot turns on the spot
    safety_margin: float = 0.08     # lateral clearance kept to laser points (m)
    slowdown_distance: float = 0.8  # obstacles closer than this (beyond the radius) slow it
    dynamic_margin: float = 0.1     # extra clearance kept to moving obstacles (m)
    reaction_time: float = 0.3      # s from seeing an obstacle to the stop taking effect
    xy_goal_tolerance: float = 0.4


@dataclass
class Command:
    v: float
    w: float
    blocked: bool = False        # something in the way: the robot cannot advance
    done: bool = False           # within goal tolerance
    index: int = 0               # closest path index


def _limit(target, current, acc, dt):
    step = acc * dt
    return min(max(target, current - step), current + step)


def front_clearance(points_robot, v, w, radius, horizon, step=0.1):
    """Free distance (m) along the arc (v, w) before the robot disc (inflated ``radius``)
    touches a point (robot frame, (N, 2)); ``horizon`` if none within it. Negative
    curvature/backwards driving is handled by the sign of v."""
    pts = np.asarray(points_robot, dtype=float).reshape(-1, 2)
    if not len(pts):
        return horizon
    direction = 1.0 if v >= 0 else -1.0
    curv = 0.0 if abs(v) < 1e-6 else w / v
    # quick reject: points farther than horizon + radius
    near = pts[np.hypot(pts[:, 0], pts[:, 1]) <= horizon + radius]
    if not len(near):
        return horizon
    n = max(2, int(math.ceil(horizon / step)) + 1)
    s = np.linspace(0.0, horizon, n) * direction
    if abs(curv) < 1e-6:
        xs, ys = s, np.zeros_like(s)
    else:
        th = s * curv
        xs, ys = np.sin(th) / curv, (1.0 - np.cos(th)) / curv
    d2 = (xs[:, None] - near[None, :, 0]) ** 2 + (ys[:, None] - near[None, :, 1]) ** 2
    hit = np.nonzero((d2 <= radius * radius).any(axis=1))[0]
    if not len(hit):
        return horizon
    return max(0.0, abs(s[hit[0]]) - step)


def closest_index(path, x, y, start_index):
    """Index of the point of ``path`` ((N, 2) array) closest to (x, y), searched among the 200
    points from ``start_index`` (clamped to the path) on: progress along the path is monotone,
    and a path that passes near itself again is not cut short."""
    lo = min(max(0, start_index), len(path) - 1)
    win = path[lo:lo + 200]
    d = np.hypot(win[:, 0] - x, win[:, 1] - y)
    return lo + int(np.argmin(d))


def lookahead_point(path, idx, distance):
    """The first point of ``path`` ((N, 2) array) at least ``distance`` metres of arc length
    beyond index ``idx``, or its last point. The arc length is summed over a prefix of the
    path grown until it reaches ``distance``, not over the whole remaining path."""
    n = 32
    while True:
        part = path[idx:idx + n + 1]
        acc = np.zeros(len(part))
        if len(part) > 1:
            d = np.diff(part, axis=0)
            np.cumsum(np.hypot(d[:, 0], d[:, 1]), out=acc[1:])
        if acc[-1] >= distance or idx + n + 1 >= len(path):
            break
        n *= 4
    k = int(np.searchsorted(acc, distance))
    return path[min(idx + k, len(path) - 1)]


def compute_command(pose, v_now, w_now, path, start_index, points_robot, dt, p,
                    dynamic_points=None):
    """One control step.

    Args:
        pose: (x, y, yaw) in the path's frame.
        v_now, w_now: the last command (for the acceleration limits).
        path: (N, 2) array, last point = goal.
        start_index: where to start searching the closest path point (monotone progress).
        points_robot: laser points in the robot frame (N, 2), all obstacles seen now.
        dt: control period (s).
        p: ControllerParams.
        dynamic_points: the subset the map does not explain (robot frame), possibly moving
            (e.g. another robot driving towards this one): braking for them assumes they may
            close half of the gap, and the stop distance grows with the speed (latency).

    Returns:
        Command: ``done`` within the goal tolerance, ``blocked`` when the robot cannot
        advance, ``index`` the closest path point.
    """
    path = np.asarray(path, dtype=float)
    x, y, th = pose
    goal = path[-1]
    dist_goal = math.hypot(goal[0] - x, goal[1] - y)
    if dist_goal <= p.xy_goal_tolerance:
        return Command(0.0, 0.0, done=True, index=len(path) - 1)
    idx = closest_index(path, x, y, start_index)
    target = lookahead_point(path, idx, p.lookahead + p.lookahead_gain * max(0.0, v_now))
    dx, dy = target[0] - x, target[1] - y
    c, s = math.cos(th), math.sin(th)
    tx, ty = c * dx + s * dy, -s * dx + c * dy
    alpha = math.atan2(ty, tx)
    ld = max(1e-3, math.hypot(tx, ty))
    pts = np.asarray(points_robot, dtype=float).reshape(-1, 2)
    r_safe = p.robot_radius + p.safety_margin
    if abs(alpha) > p.rotate_in_place_angle:
        return _turn_on_the_spot(alpha, v_now, w_now, pts, r_safe, dt, p, idx)
    curvature = 2.0 * math.sin(alpha) / ld
    v_t = _path_speed(alpha, curvature, dist_goal, p)
    horizon = max(0.5, v_t * v_t / (2.0 * p.acc_lim_x) + p.slowdown_distance)
    v_t, blocked = _obstacle_speed(pts, v_t, curvature, r_safe, horizon, p)
    if dynamic_points is not None and len(dynamic_points) and not blocked:
        v_t, blocked = _moving_obstacle_speed(dynamic_points, v_t, v_now, curvature, r_safe,
                                              horizon, p)
    return _arc_command(v_t, blocked, alpha, curvature, v_now, w_now, dt, p, idx)


def _turn_on_the_spot(alpha, v_now, w_now, pts, r_safe, dt, p, idx):
    """Command turning towards the heading error ``alpha`` (rad) on the spot: the forward
    speed decelerates at four times ``acc_lim_x``, and drops to 0 at once if a laser point
    of ``pts`` (robot frame) is within the stop distance along the current arc of a disc of
    radius ``r_safe``; the rotation respects ``acc_lim_th``. ``index``: ``idx``."""
    w_t = math.copysign(max(p.min_in_place_rotational_vel,
                            min(p.max_rot_vel, 1.5 * abs(alpha))), alpha)
    v_cmd = _limit(0.0, v_now, 4.0 * p.acc_lim_x, dt)
    if v_cmd > 0.0:     # still rolling forward: stop at once if anything is close ahead
        stop = 0.1 + 0.3 * v_now
        if front_clearance(pts, v_now, w_now, r_safe, max(0.5, 2 * stop)) <= stop:
            v_cmd = 0.0
    w_cmd = _limit(w_t, w_now, p.acc_lim_th, dt)
    return Command(v_cmd, w_cmd, index=idx)


def _path_speed(alpha, curvature, dist_goal, p):
    """Speed target (m/s) set by the path alone: slower the larger the heading error
    ``alpha``, able to stop at the goal ``dist_goal`` metres away, and within ``max_rot_vel``
    on an arc of ``curvature`` (1/m)."""
    v_t = p.max_vel_x * max(0.2, math.cos(alpha))
    v_t = min(v_t, math.sqrt(2.0 * p.acc_lim_x * max(0.0, dist_goal - 0.5 * p.xy_goal_tolerance))
              + p.min_vel_x)
    if abs(curvature) > 1e-6:
        v_t = min(v_t, p.max_rot_vel / abs(curvature))
    return v_t


def _obstacle_speed(pts, v_t, curvature, r_safe, horizon, p):
    """(speed target, blocked) for the speed target ``v_t`` with the laser points ``pts``
    (robot frame) on the arc of ``curvature`` within ``horizon`` metres: lowered so that the
    robot can stop before the first point a disc of radius ``r_safe`` would touch, and slowed
    near it; (0, True) when that point is within 0.1 m."""
    free = front_clearance(pts, max(v_t, 0.05), max(v_t, 0.05) * curvature, r_safe, horizon)
    blocked = False
    if free < horizon:
        # speed that still allows stopping before the obstacle, and slow down near it
        v_stop = math.sqrt(2.0 * p.acc_lim_x * max(0.0, free - 0.05))
        v_slow = p.max_vel_x * max(0.0, free) / p.slowdown_distance
        v_t = min(v_t, v_stop, max(p.min_vel_x, v_slow) if free > 0.1 else 0.0)
        if free <= 0.1:
            blocked = True
            v_t = 0.0
    return v_t, blocked


def _moving_obstacle_speed(dynamic_points, v_t, v_now, curvature, r_safe, horizon, p):
    """(speed target, blocked) for the speed target ``v_t`` with the points the map does not
    explain (robot frame), which may move towards the robot (another robot) and close the gap
    as fast as it does during the reaction time of both: the arc is checked with a disc
    ``dynamic_margin`` wider than ``r_safe`` (which catches the point before an arc that bends
    away has passed it), the robot keeps twice the reaction distance and takes half the
    stopping speed; (0, True) when the point is within that distance."""
    dyn = front_clearance(np.asarray(dynamic_points, dtype=float).reshape(-1, 2),
                          max(v_t, 0.05), max(v_t, 0.05) * curvature,
                          r_safe + p.dynamic_margin, horizon)
    stop_at = 0.1 + 2.0 * p.reaction_time * max(0.0, v_now)
    blocked = False
    if dyn < horizon:
        v_t = min(v_t, 0.5 * math.sqrt(2.0 * p.acc_lim_x * max(0.0, dyn - stop_at)))
        if dyn <= stop_at:
            blocked = True
            v_t = 0.0
    return v_t, blocked


def _arc_command(v_t, blocked, alpha, curvature, v_now, w_now, dt, p, idx):
    """Command following the arc of ``curvature`` at the speed target ``v_t`` within the
    acceleration limits (an emergency stop, ``blocked``, ignores the deceleration limit; a
    robot starting from below ``min_vel_x`` gets at least that speed). Stopped, it turns
    towards the heading error ``alpha`` unless blocked; when the angular acceleration limit
    bites, the speed drops to stay on the arc."""
    v_t = max(0.0, v_t)
    if blocked:
        v_cmd = 0.0     # emergency stop ignores the deceleration limit
    else:
        v_cmd = _limit(v_t, v_now, p.acc_lim_x, dt)
        if v_t > 0 and v_cmd < p.min_vel_x and v_now < p.min_vel_x:
            v_cmd = min(v_t, p.min_vel_x)
    w_t = v_cmd * curvature if v_cmd > 1e-3 else (
        math.copysign(min(p.max_rot_vel, 1.5 * abs(alpha)), alpha) if not blocked else 0.0)
    w_t = min(max(w_t, -p.max_rot_vel), p.max_rot_vel)
    w_cmd = _limit(w_t, w_now, p.acc_lim_th, dt)
    if v_cmd > 1e-3 and abs(w_cmd) < abs(w_t) - 1e-6:
        # angular acceleration limit bites: slow down to stay on the arc
        v_cmd = min(v_cmd, abs(w_cmd / curvature)) if abs(curvature) > 1e-6 else v_cmd
    return Command(v_cmd, w_cmd, blocked=blocked, index=idx)


def rotate_command(w_now, direction, dt, p, points_robot=None):
    """In-place rotation used by the recovery behaviour."""
    w_t = math.copysign(p.max_rot_vel * 0.6, direction)
    return Command(0.0, _limit(w_t, w_now, p.acc_lim_th, dt))


def heading_error(pose, target):
    return normalize_angle(math.atan2(target[1] - pose[1], target[0] - pose[0]) - pose[2])
