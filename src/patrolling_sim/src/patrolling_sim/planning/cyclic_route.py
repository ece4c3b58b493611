"""The original CGG's route where its Hamiltonian step fails: main cycle or longest path,
detours over the edges it misses, ``num_arcs`` found by bisection (docs/fidelity.md, CGG).

What the original's construction *does*, with its ``srand``/``rand`` draws (emulated by
:class:`patrolling_sim.planning.routes.CRand`), so every robot gets the original's route:

1. :func:`longest_cycle`: from each vertex of degree > 1 in id order, a randomised walk over
   unused edges that returns to its origin as late as it can (a neighbour with >= 4 unused
   edges beats the random draw; a dead end is undone); a found cycle is retried with seeds
   2000, 3000, 4000; the costliest cycle wins.
2. :func:`longest_path`: the same walk between every pair of degree-1 vertices (seed 1000).
3. The main route is the cycle if it has at least V // 2 entries, else the path.
4. :func:`~patrolling_sim.planning.route_detours.outbound_walk` follows the main route and
   inserts, where an edge off it is unused, a detour of at most ``num_arcs`` new vertices
   back to where it left; it succeeds if every edge was used. :func:`cyclic_route` takes the
   smallest such ``num_arcs`` as the original (1; else L, 1.5 L, 2 L ... for a main route of
   L entries, at most 100 tries; then bisection); a cycle is used as it is, a path is walked
   back (2W - 1 entries).

Memory the original reads but never wrote reads as a fresh array: a neighbour slot past a
vertex's list (up to its 8) as 0, any other unwritten slot as -1 (or, where that cannot be
modelled, :class:`RouteConstructionError`). The original bounds no search; here a search
stops after ``MAX_STEPS`` steps with that error too (the caller, CGG, then falls back to
CGG_TSP's tour). See docs/fidelity.md, CGG.
"""
from typing import List, Optional, Tuple

from patrolling_sim.planning.route_detours import (MAX_STEPS, SLOTS, RouteConstructionError,
                                                   outbound_walk)
from patrolling_sim.planning.routes import CRand

#: seed of the original's searches
SEED = 1000


class _Web:
    """Neighbour lists in the graph file's order with one "walked" flag per arc."""

    def __init__(self, pgraph):
        self.n = pgraph.n
        self.nb = [[w for w, _ in pgraph.neighbors[v]] for v in range(self.n)]
        self.cost = [[int(c) for _, c in pgraph.neighbors[v]] for v in range(self.n)]
        self.vis = [[False] * len(self.nb[v]) for v in range(self.n)]
        self.odd = 0              # reads of memory the original never wrote

    def clear(self):
        for row in self.vis:
            row[:] = [False] * len(row)

    def slot(self, v, j):
        """``id_neigh[j]`` as the original reads it (0 past the list); past the original's
        8 slots it reads other fields: not reproduced."""
        if j < len(self.nb[v]):
            return self.nb[v][j]
        self.odd += 1
        if j < SLOTS:
            return 0
        raise RouteConstructionError("CGG route: the original reads past a vertex's slots")

    def set_arc(self, v, w, value, both_all=False):
        """Flag the edge v-w: every arc v->w (the first w->v only, unless ``both_all``), as
        the original's loops do on graphs listing an edge twice."""
        for k, x in enumerate(self.nb[v]):
            if x == w:
                self.vis[v][k] = value
        for k, x in enumerate(self.nb[w]):
            if x == v:
                self.vis[w][k] = value
                if not both_all:
                    break

    def free(self, v):
        return self.vis[v].count(False)

    def walk_cost(self, walk):
        """Sum of the first listed arc's cost along ``walk``."""
        return sum(self.cost[a][self.nb[a].index(b)] for a, b in zip(walk, walk[1:]))


def _c_remove(items, x):
    """The original's in-place removal of ``x`` from a list: after a removal its index still
    advances, so of two equal neighbours in a row (an edge listed twice) one stays."""
    items = list(items)
    i = 0
    while i < len(items):
        if items[i] == x:
            del items[i]
        i += 1
    return items


def _search(web, origin, target, rng):
    """The original's randomised walk from ``origin`` to ``target`` (``target == origin``:
    a cycle) over arcs not flagged, as late as possible. Returns the walk or None."""
    cp = [origin]
    late = False                  # a dead end was met: take the target when offered
    last = -1
    steps = 0
    while (last != target or len(cp) > 1) if target == origin else last != target:
        steps += 1
        if steps > MAX_STEPS:
            raise RouteConstructionError("CGG route: search step bound exceeded")
        last = cp[-1]
        cands = [w for k, w in enumerate(web.nb[last]) if not web.vis[last][k]]
        if not cands:
            late = True
            if len(cp) <= 1:
                return None
            for k, w in enumerate(web.nb[last]):
                if len(web.nb[w]) > 1 and w not in cp:
                    web.set_arc(last, w, False)
            cp.pop()
            continue
        if target in cands:
            if late or len(cands) == 1:
                cp.append(target)
                return cp
            cands = _c_remove(cands, target)
        late = False
        pick = -1
        for w in cands:           # the last candidate with >= 4 unused edges, if any
            if web.free(w) >= 4:
                pick = w
        if pick == -1:
            pick = cands[rng.rand() % len(cands)]
        web.set_arc(last, pick, True)
        cp.append(pick)
    return None


def longest_cycle(web) -> Tuple[Optional[List[int]], int]:
    """(cycle, cost) of the costliest cycle the original's search finds (None, 0 if none)."""
    starts = [v for v in range(web.n) if len(web.nb[v]) > 1]
    best, best_cost = None, 0
    found, count, seed, i = False, 0, SEED, 0
    while i < len(starts) + 1:
        if found and count < 3:
            count, seed, i = count + 1, seed + 1000, i - 1
        else:
            count, seed = 0, SEED
            if i == len(starts):
                break
        web.clear()
        for v in range(web.n):
            if len(web.nb[v]) == 1:
                web.set_arc(v, web.nb[v][0], True)
        cyc = _search(web, starts[i], starts[i], CRand(seed))
        found = cyc is not None
        if found:
            cost = web.walk_cost(cyc)
            if cost > best_cost:
                best, best_cost = cyc, cost
        i += 1
    return best, best_cost


def longest_path(web) -> Tuple[Optional[List[int]], int]:
    """(path, cost) of the costliest path between two degree-1 vertices (None if < 2)."""
    leaves = [v for v in range(web.n) if len(web.nb[v]) == 1]
    best, best_cost = None, 0
    for a_i, a in enumerate(leaves):
        for b in leaves[a_i + 1:]:
            web.clear()
            for v in leaves:
                web.set_arc(v, web.nb[v][0], v not in (a, b))
            path = _search(web, a, b, CRand(SEED))
            if path is not None:
                cost = web.walk_cost(path)
                if cost > best_cost:
                    best, best_cost = path, cost
    return best, best_cost


def cyclic_route(pgraph) -> Tuple[List[int], dict]:
    """The original's closed route for a graph without a Hamiltonian path, as a list whose
    last entry repeats the first (a cycle) or the walk forward and back (a path), and a dict
    describing the construction (main route kind, its length, num_arcs, odd reads).

    Raises:
        RouteConstructionError: no route (see the module docstring).
    """
    web = _Web(pgraph)
    cycle, _ = longest_cycle(web)
    path, _ = longest_path(web)
    if cycle is not None and len(cycle) >= pgraph.n // 2:
        main, kind = cycle, "cycle"
    elif path is not None:
        main, kind = path, "path"
    else:
        raise RouteConstructionError("CGG route: no cycle of V/2 entries and no path between "
                                     "two degree-1 vertices")
    try:
        walk, num_arcs = _bisect(web, main)
    except IndexError:
        raise RouteConstructionError("CGG route: a detour overran the original's arrays")
    route = walk if kind == "cycle" else walk + walk[-2::-1]
    return route, {"main": kind, "main_entries": len(main), "num_arcs": num_arcs,
                   "odd_reads": web.odd}


def _bisect(web, main):
    """The original's search for the smallest ``num_arcs`` whose outbound walk covers every
    edge: 1; else an upper bound V, 1.5 V, 2 V ... (after 100 failures it keeps the last,
    failing, walk); then bisection. Returns (walk, num_arcs)."""
    n_main = len(main)
    walk, ok = outbound_walk(web, main, 1)
    if ok:
        return walk, 1
    lo, hi, factor, fails = 1, n_main, 1.0, 0
    while True:
        walk, ok = outbound_walk(web, main, hi)
        factor += 0.5
        if ok:
            break
        lo, hi = hi, int(factor * n_main)
        fails += 1
        if fails == 100:
            return walk, n_main
    arcs = (lo + hi + 1) // 2
    while True:
        walk, ok = outbound_walk(web, main, arcs)
        if ok:
            hi = arcs
            if hi - 1 == lo:
                return walk, arcs
            arcs = (lo + hi + 1) // 2
        else:
            lo = arcs
            arcs = arcs + 1 if hi - 1 == lo else (lo + hi + 1) // 2
