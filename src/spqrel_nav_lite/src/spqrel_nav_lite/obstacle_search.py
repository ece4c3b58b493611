"""The global planner's searches with temporary obstacles where the box around them (see
:mod:`spqrel_nav_lite.planner`) cannot settle the path: both give a field whose path from the
start is optimal on the whole map.

Window search (``obstacle_search="window"``, scipy's Dijkstra): the search runs in a window
around start and goal, grown until it is provably exact. A path that leaves the window passes
a cell ``b`` just outside it and costs at least ``|start - b| + d_free(b)`` (edge costs are at
least their length, and obstacles only remove edges), so a window path no dearer than the
smallest such bound is optimal on the whole map. The window grows (doubling its margin) until
that holds or it covers the map.

A* path field (``obstacle_search="astar"``, :mod:`~spqrel_nav_lite.grid_search`, in C++): one
A* from the robot's cell, guided by the goal's obstacle-free function (or a lower bound of it),
which obstacles can only raise (a consistent heuristic: the path is optimal). It expands little
more than the detour's cells, where a window search relaxes every cell of its window. Among
equally cheap paths it returns the one a Dijkstra field from the goal gives, as the box and
window searches do (docs/navigation.md). The field holds the path (exact) and a one-cell band
beside it (back onto the path: an upper bound), so that a robot following the path, often a
cell off it, keeps walking the same path and gets its remaining cost; a robot outside the band
is searched again from where it is.

Every field here is indexed by grid cell (row-major, ``j * w + i``), with dist inf and pred
-9999 where it has no value; ``obstacles`` is the (h, w) boolean mask of the cells the
temporary obstacles forbid.
"""
import math

import numpy as np
from scipy.sparse.csgraph import dijkstra

from . import grid_search
from .planner_grid import NEIGHBOURS, edge_cost, embed_field, window_cells, window_graph

WINDOW_MARGIN = 2.0     # metres around start and goal for the first windowed search


def window_search(grid, obstacles, g, i0, j0, i1, j1):
    """Dijkstra from grid cell ``g`` over the cells of [i0, i1) x [j0, j1) of ``grid`` (a
    :class:`~spqrel_nav_lite.planner_grid.PlannerGrid`) without the ``obstacles``' cells;
    (dist, pred) indexed by window cell (row-major), pred -9999 at roots."""
    graph = window_graph(grid, obstacles, i0, j0, i1, j1)
    ww = i1 - i0
    gl = (g // grid.w - j0) * ww + g % grid.w - i0
    return dijkstra(graph, directed=True, indices=gl, return_predecessors=True)


def outside_bound(grid, obstacles, si, sj, free_dist, i0, j0, i1, j1):
    """Lower bound on the cost of any path from cell (si, sj) that leaves the window
    [i0, i1) x [j0, j1): over the cells just outside it that no obstacle forbids,
    straight-line distance from the start plus ``free_dist`` (per grid cell, the
    obstacle-free cost to the goal or a lower bound of it); inf if there is no such cell."""
    w, h = grid.w, grid.h
    ring = []
    if j0 > 0:
        ring.append((np.arange(max(0, i0 - 1), min(w, i1 + 1)), np.full(1, j0 - 1)))
    if j1 < h:
        ring.append((np.arange(max(0, i0 - 1), min(w, i1 + 1)), np.full(1, j1)))
    if i0 > 0:
        ring.append((np.full(1, i0 - 1), np.arange(j0, j1)))
    if i1 < w:
        ring.append((np.full(1, i1), np.arange(j0, j1)))
    best = np.inf
    flat = obstacles.ravel()
    for ii, jj in ring:
        ii, jj = np.broadcast_arrays(ii, jj)
        idx = jj * w + ii
        lb = np.hypot(ii - si, jj - sj) * grid.res + free_dist[idx]
        lb = lb[~flat[idx]]
        if len(lb):
            best = min(best, float(lb.min()))
    return best


def window_field(grid, obstacles, s, g, free_dist):
    """The window search (module notes) from goal cell ``g`` for start cell ``s``:
    ``free_dist`` is, per grid cell, the obstacle-free cost to ``g`` or a lower bound of it.

    Returns ``(field, searches)``: ``field`` is (dist, pred, (i0, j0, i1, j1)), whole-grid
    arrays of the first window whose path from ``s`` is optimal on the whole map, or None
    when the window grew to cover the whole map (the caller then searches the whole map);
    ``searches`` is the number of Dijkstra runs made."""
    w, h = grid.w, grid.h
    si, sj, gi, gj = s % w, s // w, g % w, g // w
    margin = max(int(math.ceil(WINDOW_MARGIN / grid.res)),
                 max(abs(si - gi), abs(sj - gj)) // 2)
    searches = 0
    while True:
        i0, i1 = max(0, min(si, gi) - margin), min(w, max(si, gi) + margin + 1)
        j0, j1 = max(0, min(sj, gj) - margin), min(h, max(sj, gj) + margin + 1)
        if i0 == 0 and j0 == 0 and i1 == w and j1 == h:
            return None, searches
        dist, pred = window_search(grid, obstacles, g, i0, j0, i1, j1)
        searches += 1
        ww = i1 - i0
        cost = dist[(sj - j0) * ww + (si - i0)]
        if cost <= outside_bound(grid, obstacles, si, sj, free_dist, i0, j0, i1, j1):
            break
        margin *= 2
    full_d, full_p = embed_field(window_cells(w, i0, j0, i1, j1), dist, pred,
                                 np.full(w * h, np.inf, dtype=np.float32),
                                 np.full(w * h, -9999, dtype=np.int32))
    return (full_d, full_p, (i0, j0, i1, j1)), searches


def path_field(grid, obstacles, heur, s, g):
    """The A* path field (module notes) from cell ``s`` to ``g``, guided by ``heur`` (per
    grid cell, the obstacle-free cost to ``g`` or a lower bound of it).

    Returns ``(dist, pred, expanded)``: on the path's cells their exact cost to ``g`` and
    next cell (pred -9999 at ``g``); on the open cells beside the path (one step off it) the
    cost of stepping back onto it and following it, an upper bound; dist inf and pred -9999
    elsewhere, everywhere if there is no path. ``expanded``: the cells the A* expanded."""
    cells, _, expanded = grid_search.astar(grid.lethal, obstacles, grid.cost, heur, grid.res,
                                           s, g)
    w, n = grid.w, grid.w * grid.h
    dist = np.full(n, np.inf, dtype=np.float32)
    pred = np.full(n, -9999, dtype=np.int32)
    if cells is None:
        return dist, pred, expanded
    cost = grid.cost.ravel()
    steps = np.zeros(len(cells))
    i, j = cells % w, cells // w
    steps[:-1] = edge_cost(np.hypot(np.diff(i), np.diff(j)) * grid.res, cost[cells[:-1]],
                           cost[cells[1:]])
    togo = np.cumsum(steps[::-1])[::-1]         # cost from each path cell to g
    q, via, c = path_band(grid, obstacles, cells, togo)
    dist[q], pred[q] = c, via
    dist[cells], pred[cells[:-1]] = togo, cells[1:]     # path cells keep their own
    pred[g] = -9999
    return dist, pred, expanded


def path_band(grid, obstacles, cells, togo):
    """The band beside the path ``cells`` (grid cell indices, ``togo`` their cost to the
    goal): ``(q, via, c)``, each open neighbour ``q`` of a path cell (once, with no corner
    cutting past a lethal cell), linked to the path neighbour ``via`` through which its cost
    ``c`` of stepping onto the path and following it is least. Path cells may be among the
    ``q``: the caller overwrites them."""
    w, h, lethal = grid.w, grid.h, grid.lethal
    cost = grid.cost.ravel()
    i, j = cells % w, cells // w
    # lethal and obstacles read at those cells: a blocked mask would build a whole grid
    q, via, c = [], [], []
    for dj, di in NEIGHBOURS:
        qi, qj = i + di, j + dj
        ok = (qi >= 0) & (qi < w) & (qj >= 0) & (qj < h)
        ok[ok] &= ~lethal[qj[ok], qi[ok]] & ~obstacles[qj[ok], qi[ok]]
        if di and dj:           # no corner cutting past a forbidden (static) cell
            ok[ok] &= ~lethal[j[ok], qi[ok]] & ~lethal[qj[ok], i[ok]]
        qc = qj[ok] * w + qi[ok]
        q.append(qc)
        via.append(cells[ok])
        c.append(togo[ok] + edge_cost(math.hypot(di, dj) * grid.res, cost[qc],
                                      cost[cells[ok]]))
    q, via, c = np.concatenate(q), np.concatenate(via), np.concatenate(c)
    order = np.lexsort((c, q))
    first = np.ones(len(order), dtype=bool)
    first[1:] = q[order][1:] != q[order][:-1]
    return q[order][first], via[order][first], c[order][first]
