"""Optimised start positions (``--initpos optimised``): start vertices chosen for the
algorithm that will patrol.

- **Cyclic strategies** (every strategy that follows one closed route shared by the team:
  CGG, CGG_TSP, ...): the route is asked *of the strategy itself* -- the registered class is
  instantiated on each candidate start vertex and its ``route`` read after ``start()`` -- so
  whatever route and rotation rule the algorithm uses, the robots are spread along the walk
  it will really follow. The robots are then placed so that the travel times between
  consecutive robots along the closed walk (edge length / speed + goal wait per vertex) are
  as equal as the vertex positions allow: for each candidate as the first robot, every other
  robot takes the free candidate closest to its ideal offset ``i * T / N``; the set with the
  smallest largest gap wins.
- **Partition strategies** (MSP): one robot per part, robot i on the vertex of part i that
  minimises the largest shortest-path cost to the rest of its part (its centre). The parts are
  those MSP itself uses for that map and team size: the valid shipped route files, else
  :func:`patrolling_sim.planning.routes.balanced_partition` (through :func:`msp.msp_route`).
- **Any other strategy**: a k-centre -- the vertex set minimising the largest shortest-path
  cost from any vertex to its nearest robot. Exact (every combination is evaluated) when there
  are at most ``EXACT_LIMIT`` combinations; otherwise greedy farthest-point placement followed
  by single-vertex swaps while the largest cost (then the sum of costs) decreases -- a local
  optimum, at most twice the optimum (the farthest-point bound).

Only vertices where a robot fits (free cell, robot-radius clearance) are used. The result is
deterministic.
"""
import itertools
import logging
import math
import random

import numpy as np

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import write_atomic
from patrolling_sim.algorithms import REGISTRY
from patrolling_sim.algorithms import StrategyContext
from patrolling_sim.algorithms import create
from patrolling_sim.algorithms.msp import MultilevelSubgraphPatrolling
from patrolling_sim.algorithms.msp import msp_route
from patrolling_sim.common import paths
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.model.graph import load_graph
from patrolling_sim.startpos.initial_poses import ROBOT_RADIUS
from patrolling_sim.startpos.initial_poses import check_start_positions
from patrolling_sim.startpos.initial_poses import compute_start_positions
from patrolling_sim.startpos.initial_poses import spread_vertices

log = logging.getLogger(__name__)

#: k-centre by enumeration up to this many combinations
EXACT_LIMIT = 50000
#: s: the agents' random start delay is at most this long; a cyclic start that is better than
#: the default by less than that is no measurable gain, so the default start is kept
START_JITTER = 1.0


class _NullDriver:
    """Driver for probing a strategy's route: no world, no messages."""

    def now(self):
        return 0.0

    def send(self, data):
        pass

    def call_later(self, delay, fn):
        pass

    def redirect(self, vertex):
        pass


def strategy_kind(alg):
    """'cyclic', 'partition' or 'other' for a registered algorithm name."""
    cls = REGISTRY.get(alg)
    if cls is None:
        raise PatrolInputError(f"argument --alg: unknown algorithm '{alg}'")
    if issubclass(cls, MultilevelSubgraphPatrolling):
        return "partition"
    if callable(getattr(cls, "build_route", None)) and getattr(cls, "shared_route", True):
        return "cyclic"                          # follows one closed route (CGG, CGG_TSP)
    return "other"


def probe_route(pgraph, alg, n, map_name, vertex, params=None):
    """The closed walk (first == last) the strategy ``alg`` follows when started on
    ``vertex`` (robot 0 of a team of ``n``)."""
    ctx = StrategyContext(pgraph, 0, n, map_name, random.Random(0), _NullDriver(),
                          dict(params or {}), tuple(float(c) for c in pgraph.pos[vertex]))
    s = create(alg, ctx)
    s.start(vertex, 0.0)
    return list(s.route)


def _cycle_offset(ref, cyc):
    """k such that ``ref`` rotated left by k equals ``cyc`` (lists without the repeated
    end), or None."""
    if len(ref) != len(cyc):
        return None
    for k in (i for i, v in enumerate(ref) if v == cyc[0]):
        if ref[k:] + ref[:k] == cyc:
            return k
    return None


def cyclic_start_vertices(pgraph, alg, n, map_name, usable, speed=1.0, goal_wait=0.0,
                          params=None, baseline=None):
    """Start vertices evenly spaced by travel time along the strategy's closed walk.

    ``baseline``: another start (e.g. the default one); it is kept unless the optimised start
    is better on the route model by more than :data:`START_JITTER`."""
    cand_v = [v for v in range(pgraph.n) if usable[v]]
    ref_route = probe_route(pgraph, alg, n, map_name, cand_v[0], params)
    ref = ref_route[:-1]
    res = pgraph.resolution
    step = [pgraph.arc_cost(a, b) * res / speed + goal_wait if a != b else goal_wait
            for a, b in zip(ref_route, ref_route[1:])]
    t = np.concatenate([[0.0], np.cumsum(step)])
    T = float(t[-1])
    offsets = {}
    for v in cand_v:
        k = _cycle_offset(ref, probe_route(pgraph, alg, n, map_name, v, params)[:-1])
        if k is not None:
            offsets[v] = float(t[k])
    if len(offsets) < n or T <= 0:
        return None
    cands = sorted(offsets.items(), key=lambda kv: (kv[1], kv[0]))
    times = np.array([c[1] for c in cands])
    # every vertex's passes along the walk: its steady-state idleness is the largest gap
    # between consecutive passes of any robot (a vertex may occur several times on the walk)
    occ_v = np.array(ref)
    occ_t = t[:-1]

    def score(chosen):
        starts = times[chosen]
        pass_t = (occ_t[None, :] - starts[:, None]) % T          # (robots, occurrences)
        worst_gap = 0.0
        for v in np.unique(occ_v):
            ts = np.sort(pass_t[:, occ_v == v].ravel())
            gaps = np.diff(np.concatenate([ts, [ts[0] + T]]))
            worst_gap = max(worst_gap, float(gaps.max()))
        ts = np.sort(starts)
        rg = np.diff(np.concatenate([ts, [ts[0] + T]]))
        return (round(worst_gap, 6), round(float(np.square(rg - T / n).sum()), 6))

    best = None
    for a in range(len(cands)):
        chosen = [a]
        for i in range(1, n):
            target = (times[a] + i * T / n) % T
            d = np.abs(times - target)
            d = np.minimum(d, T - d)
            d[chosen] = np.inf
            chosen.append(int(np.argmin(d)))
        key = score(chosen)
        if best is None or key < best[0]:
            best = (key, chosen)
    # then single-robot moves while the worst idleness (then the spacing) improves
    key, chosen = best
    improved = True
    while improved:
        improved = False
        for i in range(n):
            for c in range(len(cands)):
                if c in chosen:
                    continue
                trial = chosen[:i] + [c] + chosen[i + 1:]
                k2 = score(trial)
                if k2 < key:
                    key, chosen, improved = k2, trial, True
    index = {v: i for i, (v, _) in enumerate(cands)}
    if baseline is not None and all(v in index for v in baseline) \
            and len(set(baseline)) == n:
        base = [index[v] for v in baseline]
        # the baseline is kept unless the optimised start beats it by more than the robots'
        # random start delays can blur (U(0, 1) s, docs/protocol.md)
        if score(base)[0] <= key[0] + START_JITTER:
            key, chosen = score(base), base
    log.debug("cyclic start for %s, %d robots: model worst idleness %.1f s", alg, n, key[0])
    return [cands[c][0] for c in chosen]


def partition_start_vertices(pgraph, n, map_name, usable, params=None):
    """Robot i on the centre of MSP's part i."""
    D = pgraph.dist
    taken = set()
    out = []
    for i in range(n):
        route, _ = msp_route(pgraph, map_name, n, i,
                             route_file=(params or {}).get("msp_route"))
        part = sorted(set(route))
        cands = [v for v in part if usable[v] and v not in taken]
        if not cands:
            return None
        ecc = [(float(np.max(D[v, part])), v) for v in cands]
        v = min(ecc)[1]
        taken.add(v)
        out.append(v)
    return out


def _kcentre_cost(D, chosen):
    m = D[chosen].min(axis=0)
    return float(m.max()), float(m.sum())


def kcentre_start_vertices(pgraph, n, usable):
    """k-centre over the usable vertices (exact or farthest-point + swaps, module doc)."""
    D = pgraph.dist.copy()
    finite = np.isfinite(D)
    D[~finite] = 10.0 * (np.max(D[finite]) + 1.0) if finite.any() else 1.0
    cand = [v for v in range(pgraph.n) if usable[v]]
    if len(cand) < n:
        return None
    if math.comb(len(cand), n) <= EXACT_LIMIT:
        best = None
        for combo in itertools.combinations(cand, n):
            key = _kcentre_cost(D, list(combo))
            if best is None or key < best[0]:
                best = (key, list(combo))
        return best[1]
    chosen = spread_vertices(pgraph, n, usable)
    key = _kcentre_cost(D, chosen)
    improved = True
    while improved:
        improved = False
        for i in range(n):
            for c in cand:
                if c in chosen:
                    continue
                trial = chosen[:i] + [c] + chosen[i + 1:]
                k2 = _kcentre_cost(D, trial)
                if k2 < key:
                    chosen, key, improved = trial, k2, True
    return chosen


def optimised_start_vertices(pgraph, n, alg, map_name, usable=None, speed=1.0,
                             goal_wait=0.0, params=None, baseline=None):
    """(vertices, method): one start vertex per robot for ``alg`` (module doc), or
    (None, reason) when the graph has fewer usable vertices than robots."""
    usable = np.ones(pgraph.n, bool) if usable is None else np.asarray(usable, bool)
    kind = strategy_kind(alg)
    verts = None
    if kind == "cyclic":
        verts = cyclic_start_vertices(pgraph, alg, n, map_name, usable, speed, goal_wait,
                                      params, baseline)
        method = "evenly spaced along the route"
    elif kind == "partition":
        verts = partition_start_vertices(pgraph, n, map_name, usable, params)
        method = "one per part, at its centre"
    if verts is None:
        verts = kcentre_start_vertices(pgraph, n, usable)
        method = "k-centre"
    if verts is None:
        return None, f"only {int(usable.sum())} usable vertices for {n} robots"
    return verts, method


def optimised_start_positions(pgraph, occupancy, n, alg, map_name, default=None):
    """(positions, source) for :func:`patrolling_sim.startpos.resolve.start_positions`:
    the optimised vertices' positions; when they cannot hold the team (more robots than
    usable vertices, or two chosen vertices closer than the start separation) the default
    computed spread is used instead and the source says so. ``default``: the default start
    positions; for cyclic strategies they are kept when the route model rates them at least
    as well (so optimised is never worse than default on the model)."""
    if not alg:
        raise PatrolInputError("--initpos optimised needs the algorithm (--alg)")
    usable = [occupancy.is_free(x, y) and occupancy.clearance_at(x, y) >= ROBOT_RADIUS
              for x, y in pgraph.pos]
    baseline = None if default is None else [pgraph.nearest_vertex(x, y) for x, y in default]
    verts, method = optimised_start_vertices(pgraph, n, alg, map_name, usable,
                                             baseline=baseline)
    if verts is not None:
        pos = [tuple(round(float(c), 3) for c in pgraph.pos[v]) for v in verts]
        problem = check_start_positions(pos, occupancy)
        if problem is None:
            return pos, f"optimised for {alg}: {method}"
        method = problem
    log.warning("optimised start positions for %s on %s with %d robots: %s; using the "
                "computed spread instead", alg, map_name, n, method)
    return compute_start_positions(pgraph, occupancy, n), "computed (optimised impossible)"


def write_start_poses(path, positions, pgraph, source):
    """Write the team's start poses (one robot a line: id, x, y, vertex) beside the results,
    atomically. ``pgraph`` is a PatrolGraph or a map name/path (its graph is loaded)."""
    if isinstance(pgraph, str):
        pgraph = PatrolGraph(load_graph(paths.map_files(pgraph)[1], warn=False))
    lines = [f"# start poses: {source}", "# robot x_m y_m vertex"]
    for k, (x, y) in enumerate(positions):
        lines.append(f"{k} {x:.3f} {y:.3f} {pgraph.nearest_vertex(x, y)}")
    write_atomic(path, "\n".join(lines) + "\n")
