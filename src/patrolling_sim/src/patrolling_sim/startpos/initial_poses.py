"""Robot start positions.

``--initpos optimised`` chooses start vertices for the algorithm instead
(:mod:`patrolling_sim.startpos.optimised`). Otherwise two sources, in this order:

1. ``params/initial_poses.txt`` (INI section ``[InitialPoses]``, keys ``<map>_<N>`` or
   ``<map>_<N>_<variant>``, values ``[x0, y0, x1, y1, ...]`` in metres), as in the original;
2. for any map and team size without an entry: :func:`compute_start_positions`, a
   deterministic spread over the graph (farthest-point sampling on shortest-path costs),
   then, once every vertex holds a robot, free cells near the vertices.

A start set is valid when every robot stands on a free cell with at least ``clearance``
metres to the nearest obstacle, no two robots are closer than ``min_separation`` and
(for computed sets) robots occupy distinct vertices while N <= V.
The yaw of every robot is pi/2, as in the original launcher.
"""
import ast
import configparser
import logging
import math

import numpy as np

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import read_text

log = logging.getLogger(__name__)

DEFAULT_YAW = math.pi / 2
#: default robot radius of the simulator (m)
ROBOT_RADIUS = 0.225
#: ``--initpos`` value selecting :mod:`patrolling_sim.startpos.optimised`
OPTIMISED = "optimised"
#: minimal distance between two robot centres at start (m)
MIN_SEPARATION = 0.6


def load_initial_poses(path):
    """Parse ``initial_poses.txt`` into ``{key: [(x, y), ...]}`` (keys lower-cased).

    Raises:
        PatrolInputError: missing file, no ``[InitialPoses]`` section, or a malformed value.
    """
    cp = configparser.ConfigParser()
    text = read_text(path, "initial poses file")
    try:
        cp.read_string(text, source=path)
    except configparser.Error as e:
        raise PatrolInputError(f"{path}: malformed INI file ({e.__class__.__name__})") from None
    if not cp.has_section("InitialPoses"):
        raise PatrolInputError(f"{path}: no [InitialPoses] section")
    table = {}
    for key, value in cp.items("InitialPoses"):
        try:
            vals = ast.literal_eval(value)
            vals = [float(v) for v in vals]
        except (ValueError, SyntaxError, TypeError):
            raise PatrolInputError(f"{path}: key '{key}': value must be a list of numbers, "
                                   f"got {value!r}") from None
        if len(vals) % 2 or not vals:
            raise PatrolInputError(f"{path}: key '{key}': expected an even, non-zero count of "
                                   f"numbers (x, y pairs), got {len(vals)}")
        table[key] = [(vals[i], vals[i + 1]) for i in range(0, len(vals), 2)]
    return table


def table_key(map_name, n, variant="default"):
    key = f"{map_name}_{n}"
    if variant and variant != "default":
        key += f"_{variant}"
    return key.lower()


def check_start_positions(positions, occupancy, clearance=ROBOT_RADIUS,
                          min_separation=MIN_SEPARATION):
    """Return None if the positions are valid, else a one-line reason."""
    for k, (x, y) in enumerate(positions):
        state = occupancy.cell_state(x, y)
        if state != "free":
            return f"robot {k} at ({x:.3f}, {y:.3f}) is on a {state} cell"
        c = occupancy.clearance_at(x, y)
        if c < clearance:
            return (f"robot {k} at ({x:.3f}, {y:.3f}) is {c:.2f} m from an obstacle "
                    f"(needs {clearance:.2f} m)")
    p = np.asarray(positions, dtype=float).reshape(-1, 2)
    if len(p) > 1:
        d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
        np.fill_diagonal(d, np.inf)
        i, j = np.unravel_index(np.argmin(d), d.shape)
        if d[i, j] < min_separation:
            return (f"robots {min(i, j)} and {max(i, j)} are {d[i, j]:.2f} m apart "
                    f"(needs {min_separation:.2f} m)")
    return None


def spread_vertices(pgraph, n, usable=None):
    """Pick ``n`` distinct vertices spread over the graph, deterministically.

    Farthest-point sampling on shortest-path costs: the first vertex is the graph centre
    (minimum eccentricity, lowest id on ties); each next one maximises the cost to the
    nearest already chosen vertex (lowest id on ties). Unreachable pairs count as far.

    Args:
        pgraph: :class:`patrolling_sim.model.graph.PatrolGraph`.
        n: how many (<= number of usable vertices).
        usable: optional boolean sequence; unusable vertices are never picked.
    """
    V = pgraph.n
    usable = np.ones(V, bool) if usable is None else np.asarray(usable, bool)
    cand = np.flatnonzero(usable)
    if n > len(cand):
        raise ValueError("not enough usable vertices")
    dist = pgraph.dist.copy()
    finite_max = np.max(dist[np.isfinite(dist)]) if np.isfinite(dist).any() else 1.0
    dist[~np.isfinite(dist)] = 10.0 * (finite_max + 1.0)
    ecc = dist[np.ix_(cand, cand)].max(axis=1)
    chosen = [int(cand[int(np.argmin(ecc))])]
    nearest = dist[chosen[0]].copy()
    while len(chosen) < n:
        score = np.where(usable, nearest, -1.0)
        score[chosen] = -1.0
        v = int(np.argmax(score))
        chosen.append(v)
        nearest = np.minimum(nearest, dist[v])
    return chosen


def compute_start_positions(pgraph, occupancy, n, clearance=ROBOT_RADIUS,
                            min_separation=MIN_SEPARATION):
    """Deterministic, collision-free start positions for ``n`` robots (see module doc).

    Returns:
        list of (x, y) in metres.

    Raises:
        PatrolInputError: the map cannot hold ``n`` robots.
    """
    if n < 1:
        raise PatrolInputError(f"team size must be >= 1, got {n}")
    ok = np.array([occupancy.is_free(x, y) and occupancy.clearance_at(x, y) >= clearance
                   for x, y in pgraph.pos])
    on_vertices = spread_vertices(pgraph, min(n, int(ok.sum())), ok)
    positions = [tuple(pgraph.pos[v]) for v in on_vertices]
    # keep vertex positions mutually separated (vertices closer than min_separation: skip)
    positions = _drop_crowded(positions, min_separation)
    if len(positions) < n:
        positions = _fill_near_vertices(pgraph, occupancy, positions, n, clearance,
                                        min_separation)
    if len(positions) < n:
        raise PatrolInputError(
            f"map '{pgraph.name}' cannot hold {n} robots: only {len(positions)} "
            f"collision-free start positions (clearance {clearance} m, separation "
            f"{min_separation} m) near its graph")
    return positions


def _drop_crowded(positions, min_sep):
    kept = []
    for p in positions:
        if all(math.hypot(p[0] - q[0], p[1] - q[1]) >= min_sep for q in kept):
            kept.append(p)
    return kept


def _fill_near_vertices(pgraph, occupancy, positions, n, clearance, min_sep):
    """Add positions on free cells around the vertices: rings of growing radius, vertices
    visited round-robin in spread order, 16 directions per ring."""
    order = spread_vertices(pgraph, pgraph.n)
    positions = list(positions)
    pts = np.array(positions, dtype=float).reshape(-1, 2)
    max_radius = max(3.0, 8 * min_sep)
    radius = min_sep
    angles = [2 * math.pi * k / 16 for k in range(16)]
    while len(positions) < n and radius <= max_radius:
        added = True
        while added and len(positions) < n:
            added = False
            for v in order:
                vx, vy = pgraph.pos[v]
                for a in angles:
                    x, y = vx + radius * math.cos(a), vy + radius * math.sin(a)
                    x, y = round(x, 3), round(y, 3)
                    if not occupancy.is_free(x, y) or occupancy.clearance_at(x, y) < clearance:
                        continue
                    if len(pts) and np.min(np.hypot(pts[:, 0] - x, pts[:, 1] - y)) < min_sep:
                        continue
                    positions.append((x, y))
                    pts = np.vstack([pts, [x, y]])
                    added = True
                    break
                if len(positions) >= n:
                    break
        radius += min_sep / 2
    return positions


def table_positions(map_name, n, pgraph, occupancy, initpos="default", table=None,
                    table_path=None):
    """Start positions for ``n`` robots on ``map_name`` from the original's table, or a
    computed spread.

    Uses the table entry ``<map>_<n>[_<initpos>]`` if present and valid. A named variant
    (``initpos`` != "default") must exist. A missing or invalid default entry falls back to
    :func:`compute_start_positions` (an invalid entry is logged). The "optimised" variant is
    resolved one level up, by :func:`patrolling_sim.startpos.resolve.start_positions`.

    Returns:
        (positions, source): positions is a list of (x, y); source is "table" or "computed".

    Raises:
        PatrolInputError: ``n`` < 1, a named variant missing or unusable, an entry with the
        wrong number of poses.
    """
    if n < 1:
        raise PatrolInputError(f"team size must be >= 1, got {n}")
    key = table_key(map_name, n, initpos)
    entry = (table or {}).get(key)
    where = table_path or "initial poses table"
    if entry is not None:
        if len(entry) != n:
            raise PatrolInputError(f"{where}: key '{key}' has {len(entry)} poses, expected {n}")
        problem = check_start_positions(entry, occupancy)
        if problem is None:
            return list(entry), "table"
        if initpos not in ("default", "", None):
            raise PatrolInputError(f"{where}: key '{key}': {problem}")
        log.warning("%s: key '%s' is unusable (%s); computing start positions instead",
                    where, key, problem)
    elif initpos not in ("default", "", None):
        raise PatrolInputError(f"{where}: no entry '{key}' for initial positions "
                               f"'{initpos}' of map '{map_name}' with {n} robots")
    return compute_start_positions(pgraph, occupancy, n), "computed"
