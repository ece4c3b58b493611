"""Closed patrol routes and balanced graph partitions (pure functions over PatrolGraph).

- :func:`closed_route` returns a short closed walk visiting every vertex of a (sub)graph:
  a travelling-salesman tour over shortest-path costs (nearest-neighbour starts improved by
  2-opt and Or-opt moves, deterministic for a given seed), expanded into graph edges. On
  graphs with a Hamiltonian circuit this finds one (or close); on trees it is the
  depth-first walk that traverses every edge twice; on grid (25 vertices) it gives the 26-edge
  walk of 148.2 m.
- :func:`balanced_partition` splits a connected graph into k connected regions of nearly
  equal size by recursive bisection (a region grows from a peripheral vertex in shortest-path
  order, so it is connected; the split is kept only if the rest is connected too).

- :func:`hamiltonian_route` is the original CGG's route where its first construction step
  succeeds: a randomised greedy walk from each vertex in turn (``rand()`` reseeded with 1000
  before each walk, emulated by :class:`CRand`) that either visits every vertex (a
  Hamiltonian path; a circuit if its ends are adjacent) or gets stuck. A circuit is used as
  it is; a path is closed by walking it back. On grid this gives the original's 49-step
  route. It returns None where the original goes on to its longest-cycle / longest-path
  construction (every other shipped map; :mod:`patrolling_sim.planning.cyclic_route`).

All are deterministic: every robot computes the same result from the same graph.
"""
import random
from typing import List, Optional, Sequence

import numpy as np
import networkx as nx


class CRand:
    """The C library's ``srand(seed)`` / ``rand()`` as glibc implements them (additive
    feedback generator, 31-word state, the first 310 outputs discarded), so that a
    construction the original seeds with a fixed value gives the same choices here.
    Checked against glibc: seed 1 gives 1804289383, 846930886, 1681692777."""

    MOD = 2147483647

    def __init__(self, seed: int):
        r = [0] * 34
        r[0] = seed & 0xFFFFFFFF or 1
        for i in range(1, 31):
            prev = r[i - 1] - (1 << 32) if r[i - 1] >= 1 << 31 else r[i - 1]
            hi, lo = divmod(prev, 127773)
            word = 16807 * lo - 2836 * hi
            r[i] = word + self.MOD if word < 0 else word
        for i in range(31, 34):
            r[i] = r[i - 31]
        self._r = r
        for _ in range(310):
            self.rand()

    def rand(self) -> int:
        r = self._r
        v = (r[-31] + r[-3]) & 0xFFFFFFFF
        r.append(v)
        if len(r) > 96:
            del r[:-31]
        return v >> 1


#: the seed the original's Hamiltonian walk uses before every attempt
HAMILTON_SEED = 1000


def hamiltonian_walk(pgraph, first: int) -> Optional[List[int]]:
    """The original's randomised greedy walk from ``first``: repeatedly move to a neighbour
    (in the graph file's order) not yet on the walk, chosen by ``rand() % count`` after
    ``srand(1000)``; the vertex list if it covers the graph, None if it gets stuck."""
    rng = CRand(HAMILTON_SEED)
    walk = [first]
    on = {first}
    while len(walk) < pgraph.n:
        free = [w for w, _ in pgraph.neighbors[walk[-1]] if w not in on]
        if not free:
            return None
        w = free[rng.rand() % len(free)]
        walk.append(w)
        on.add(w)
    return walk


def hamiltonian_route(pgraph) -> Optional[List[int]]:
    """The original CGG's route when its Hamiltonian step succeeds, else None.

    Walks are tried from every vertex in id order: the first Hamiltonian *circuit* wins
    (closed by repeating its first vertex); otherwise the last Hamiltonian *path* found is
    closed by walking it back (2L - 1 entries)."""
    found = None
    for v in range(pgraph.n):
        walk = hamiltonian_walk(pgraph, v)
        if walk is None:
            continue
        if pgraph.n > 1 and pgraph.arc_cost(walk[-1], walk[0]) is not None:
            return walk + walk[:1]
        found = walk
    if found is None:
        return None
    return found + found[-2::-1] if len(found) > 1 else [found[0], found[0]]


def route_cost(pgraph, route: Sequence[int]) -> float:
    """Sum of arc costs (px) along consecutive vertices of ``route``."""
    return float(sum(pgraph.arc_cost(a, b) for a, b in zip(route, route[1:]) if a != b))


def _tour_cost(D, tour):
    return sum(D[tour[i], tour[(i + 1) % len(tour)]] for i in range(len(tour)))


def two_opt(D, tour):
    """2-opt: for each position i, reverse the segment that shortens the tour most, until no
    reversal helps (the candidate j are scored together with numpy)."""
    t = np.array(tour)
    n = len(t)
    improved = True
    while improved:
        improved = False
        for i in range(n - 1):
            j = np.arange(i + 2, n if i > 0 else n - 1)
            if not len(j):
                continue
            a, b = t[i], t[i + 1]
            c, d = t[j], t[(j + 1) % n]
            delta = D[a, c] + D[b, d] - D[a, b] - D[c, d]
            k = int(np.argmin(delta))
            if delta[k] < -1e-9:
                jj = int(j[k])
                t[i + 1:jj + 1] = t[i + 1:jj + 1][::-1].copy()
                improved = True
    return t.tolist()


def or_opt(D, tour):
    """Or-opt: move a segment of 1-3 vertices (either way round) to where it shortens the tour
    most, while some move helps (all insertion points scored together with numpy)."""
    t = np.array(tour)
    n = len(t)
    improved = True
    while improved:
        improved = False
        for seg in (1, 2, 3):
            if seg >= n - 2:
                break
            for i in range(n):
                s0, s1 = t[i], t[(i + seg - 1) % n]
                prev, nxt = t[(i - 1) % n], t[(i + seg) % n]
                remove_gain = D[prev, s0] + D[s1, nxt] - D[prev, nxt]
                rest = np.roll(t, -(i + seg))[:n - seg]
                p, q = rest[:-1], rest[1:]
                base = D[p, q]
                fwd = D[p, s0] + D[s1, q] - base          # segment as is
                rev = D[p, s1] + D[s0, q] - base          # reversed
                kf, kr = int(np.argmin(fwd)), int(np.argmin(rev))
                add, j, flip = (fwd[kf], kf, False) if fwd[kf] <= rev[kr] else (rev[kr], kr, True)
                if add < remove_gain - 1e-9:
                    segment = np.roll(t, -i)[:seg]
                    if flip:
                        segment = segment[::-1]
                    t = np.concatenate([rest[:j + 1], segment, rest[j + 1:]])
                    improved = True
    return t.tolist()


def _nearest_neighbour(D, start, vertices):
    tour = [start]
    left = set(vertices) - {start}
    while left:
        last = tour[-1]
        nxt = min(left, key=lambda v: (D[last, v], v))
        tour.append(nxt)
        left.remove(nxt)
    return tour


def tsp_tour(D, vertices: Sequence[int], seed: int = 1000, restarts: Optional[int] = None):
    """A short closed tour (list, no repeated endpoint) over ``vertices`` with metric ``D``."""
    vertices = list(vertices)
    if len(vertices) <= 3:
        return vertices
    rng = random.Random(seed)
    if restarts is None:
        restarts = 8 if len(vertices) <= 60 else 3
    starts = [vertices[0]] + rng.sample(vertices, min(restarts, len(vertices)) - 1)
    best, best_cost = None, float("inf")
    for s in starts:
        tour = or_opt(D, two_opt(D, _nearest_neighbour(D, s, vertices)))
        cost = _tour_cost(D, tour)
        if cost < best_cost - 1e-9:
            best, best_cost = tour, cost
    return best


def closed_route(pgraph, vertices: Optional[Sequence[int]] = None, seed: int = 1000) -> List[int]:
    """A closed walk (first == last) visiting every vertex of ``vertices`` (default: all).

    The walk only uses shortest paths inside the subgraph induced by ``vertices``, which
    must be connected. A single vertex gives ``[v, v]``.
    """
    verts = sorted(range(pgraph.n) if vertices is None else set(vertices))
    if len(verts) == 1:
        return [verts[0], verts[0]]
    # every robot of a team asks for the same route: computed once per graph object
    cache = pgraph.derived.setdefault("closed_route", {})
    key = (tuple(verts), seed)
    if key not in cache:
        cache[key] = _closed_route(pgraph, verts, seed)
    return list(cache[key])


def _closed_route(pgraph, verts, seed):
    D, paths = _subgraph_metric(pgraph, tuple(verts))
    tour = tsp_tour(D, verts, seed=seed)
    walk = [tour[0]]
    for a, b in zip(tour, tour[1:] + tour[:1]):
        walk.extend(paths(a, b)[1:])
    return walk


def _subgraph_metric(pgraph, verts):
    if len(verts) == pgraph.n:
        return pgraph.dist, pgraph.path
    # cached on the graph object itself (no module-level state shared between graphs)
    cache = pgraph.derived.setdefault("sub_metric", {})
    if verts not in cache:
        cache[verts] = _sub_metric(pgraph, verts)
    return cache[verts]


def _sub_metric(pgraph, verts):
    allowed = set(verts)
    G = nx.DiGraph()
    G.add_nodes_from(verts)
    for u in verts:
        for w in pgraph.neighbor_ids(u):
            if w in allowed:
                G.add_edge(u, w, weight=pgraph.arc_cost(u, w))
    D = np.full((pgraph.n, pgraph.n), np.inf)
    P = {}
    for s in verts:
        dist, path = nx.single_source_dijkstra(G, s, weight="weight")
        for t, d in dist.items():
            D[s, t] = d
            P[(s, t)] = path[t]
    missing = [t for t in verts if D[verts[0], t] == np.inf]
    if missing:
        raise ValueError(f"vertices {missing[:5]} are not connected to {verts[0]} in the region")
    return D, lambda a, b: P[(a, b)]


def _connected(pgraph, verts):
    verts = set(verts)
    if not verts:
        return True
    start = next(iter(verts))
    seen, stack = {start}, [start]
    while stack:
        u = stack.pop()
        for w in pgraph.neighbor_ids(u):
            if w in verts and w not in seen:
                seen.add(w)
                stack.append(w)
    return seen == verts


def _bisect(pgraph, verts, size_a):
    """Split ``verts`` into (A, B), both connected, |A| as close to ``size_a`` as possible.

    For every root, build the breadth-first spanning tree of the region; cutting one tree
    edge leaves two connected parts (a subtree and the rest). Take the cut whose subtree size
    is closest to ``size_a`` (or to the complement), first root wins ties.
    """
    vs = sorted(verts)
    allowed = set(vs)
    best = None
    for root in vs:
        parent = {root: None}
        order = [root]
        for u in order:
            for w in sorted(pgraph.neighbor_ids(u)):
                if w in allowed and w not in parent:
                    parent[w] = u
                    order.append(w)
        if len(order) != len(vs):
            raise ValueError("region is not connected")
        size = {v: 1 for v in vs}
        for v in reversed(order[1:]):
            size[parent[v]] += size[v]
        for v in order[1:]:
            for k, as_a in ((size[v], True), (len(vs) - size[v], False)):
                err = abs(k - size_a)
                if best is None or err < best[0]:
                    best = (err, root, v, as_a, parent)
        if best is not None and best[0] == 0:
            break
    if best is None:
        return None
    _, root, cut, as_a, parent = best
    sub = set()
    for v in vs:            # v is in cut's subtree if walking up reaches cut
        u = v
        while u is not None and u != cut:
            u = parent[u]
        if u == cut:
            sub.add(v)
    rest = [v for v in vs if v not in sub]
    sub = sorted(sub)
    return (sub, rest) if as_a else (rest, sub)


def balanced_partition(pgraph, k: int, vertices: Optional[Sequence[int]] = None) -> List[List[int]]:
    """Split the (connected) vertex set into ``k`` connected regions of near-equal size.

    With ``k`` larger than the vertex count, regions repeat (several robots share one
    vertex region). Regions are returned in a deterministic order.
    """
    verts = sorted(range(pgraph.n) if vertices is None else vertices)
    if k < 1:
        raise ValueError("k must be >= 1")
    cache = pgraph.derived.setdefault("partition", {})
    key = (tuple(verts), k)
    if key not in cache:
        cache[key] = _balanced_partition(pgraph, k, verts)
    return [list(p) for p in cache[key]]


def _balanced_partition(pgraph, k, verts):
    if k == 1:
        return [verts]
    if k >= len(verts):
        singles = [[v] for v in verts]
        return [singles[i % len(singles)] for i in range(k)]
    k_a = k // 2
    size_a = round(len(verts) * k_a / k)
    split = _bisect(pgraph, verts, max(1, size_a))
    if split is None:          # cannot split while keeping both sides connected
        return [verts for _ in range(k)]
    a, b = split
    k_a = min(max(1, round(k * len(a) / len(verts))), k - 1)
    return balanced_partition(pgraph, k_a, a) + balanced_partition(pgraph, k - k_a, b)
