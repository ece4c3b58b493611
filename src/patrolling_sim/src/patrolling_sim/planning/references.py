"""Theoretical reference figures for a map and a team size (see ``docs/metrics.md``).

They tell a user how far an algorithm is from what a well-organised team could do:

- **best closed tour** ``L`` (m): the shortest closed walk through every vertex we can find —
  exact (Held-Karp dynamic programming over shortest-path costs) for graphs of at most
  :data:`EXACT_MAX_VERTICES` vertices, otherwise the best of networkx's Christofides tour and
  our own nearest-neighbour + 2-opt/Or-opt tour
  (:func:`patrolling_sim.planning.routes.closed_route`), refined again by 2-opt/Or-opt;
- **cyclic reference** ``L / (k v)`` (s): the idleness every vertex reaches at most when k
  robots at speed v are evenly spaced along that tour (Chevaleyre 2004's bound for cyclic
  strategies);
- **partition reference** (s): the slowest part of a balanced partition — max over the k
  parts of (closed tour of the part) / v — i.e. the worst idleness of a partition strategy
  on the partition we find (:func:`patrolling_sim.planning.routes.balanced_partition`).

All three ignore goal waits and interference: they are lower-bound-like references, not
predictions. Pure functions over :class:`~patrolling_sim.model.graph.PatrolGraph`.
"""
from dataclasses import dataclass
from typing import List, Sequence

import networkx as nx
import numpy as np

from patrolling_sim.planning.routes import or_opt, two_opt, balanced_partition, closed_route

#: up to this many vertices the closed tour is computed exactly (Held-Karp: 2^n n^2 steps)
EXACT_MAX_VERTICES = 13


@dataclass
class References:
    """Reference figures of one map and team size (lengths in m, times in s)."""
    map: str
    team_size: int
    speed: float
    tour_length: float
    tour_exact: bool
    cyclic_idleness: float
    partition_idleness: float
    partition_sizes: List[int]


def _metric(pgraph, verts: Sequence[int]) -> np.ndarray:
    """Shortest-path costs (m) between ``verts`` over the whole graph."""
    d = np.asarray(pgraph.dist, dtype=float) * pgraph.resolution
    idx = np.asarray(verts)
    return d[np.ix_(idx, idx)]


def _held_karp(D: np.ndarray) -> float:
    """Exact shortest closed tour through every row of the metric ``D`` (n <= ~13)."""
    n = len(D)
    if n <= 1:
        return 0.0
    if n == 2:
        return float(2 * D[0, 1])
    full = 1 << (n - 1)                       # subsets of vertices 1..n-1
    best = np.full((full, n - 1), np.inf)
    for j in range(n - 1):
        best[1 << j, j] = D[0, j + 1]
    for subset in range(1, full):
        row = best[subset]
        for j in range(n - 1):
            if not subset & (1 << j) or not np.isfinite(row[j]):
                continue
            rest = ~subset & (full - 1)
            k = rest
            while k:
                low = k & -k
                m = low.bit_length() - 1
                cand = row[j] + D[j + 1, m + 1]
                s2 = subset | low
                if cand < best[s2, m]:
                    best[s2, m] = cand
                k ^= low
    last = best[full - 1]
    return float(min(last[j] + D[j + 1, 0] for j in range(n - 1)))


def _tour_len(D: np.ndarray, order: Sequence[int]) -> float:
    return float(sum(D[order[i], order[(i + 1) % len(order)]] for i in range(len(order))))


def best_tour_length(pgraph, verts: Sequence[int] = None) -> (float, bool):
    """(length in m, exact?) of the shortest closed walk through ``verts`` (default: all)."""
    verts = list(range(pgraph.n)) if verts is None else sorted(set(verts))
    if len(verts) <= 1:
        return 0.0, True
    D = _metric(pgraph, verts)
    if len(verts) <= EXACT_MAX_VERTICES:
        return _held_karp(D), True
    # heuristic: the better of networkx's Christofides and our own tour, refined
    K = nx.complete_graph(len(verts))
    for a, b in K.edges():
        K[a][b]["weight"] = D[a, b]
    cands = [nx.approximation.christofides(K, weight="weight")[:-1]]
    own = closed_route(pgraph, verts)[:-1]
    pos = {v: i for i, v in enumerate(verts)}
    seen, order = set(), []
    for v in own:                              # the walk's first visits, in order
        if v not in seen:
            seen.add(v)
            order.append(pos[v])
    cands.append(order)
    best = min(_tour_len(D, or_opt(D, two_opt(D, list(c)))) for c in cands)
    return best, False


def references(pgraph, team_size: int, speed: float = 1.0, map_name: str = "") -> References:
    """The three references of ``pgraph`` for ``team_size`` robots at ``speed`` m/s.

    Raises:
        ValueError: team_size < 1 or speed <= 0.
    """
    if team_size < 1:
        raise ValueError(f"team_size must be >= 1, got {team_size}")
    if speed <= 0:
        raise ValueError(f"speed must be > 0, got {speed}")
    L, exact = best_tour_length(pgraph)
    parts = balanced_partition(pgraph, team_size)
    part_tours = [best_tour_length(pgraph, p)[0] for p in parts]
    return References(map=map_name or getattr(pgraph, "name", ""), team_size=team_size,
                      speed=speed, tour_length=L, tour_exact=exact,
                      cyclic_idleness=L / (team_size * speed),
                      partition_idleness=max(part_tours) / speed,
                      partition_sizes=[len(p) for p in parts])
