"""The read-only part of the global planner, shareable by every robot of a process.

:class:`PlannerGrid` holds what depends only on the map and the planner parameters: the cost
grid (the map downsampled to the planner resolution, cells keeping the clearance of their
centre), the forbidden cells, the 8-connected edge list and its obstacle-free CSR graph.
:class:`NavFunctionCache` keeps obstacle-free navigation functions (Dijkstra from a goal cell)
in a least-recently-used cache bounded in bytes and guarded by a lock, so the robots of a
``nav_host`` process (docs/navigation.md) share the searches of goals they have in common:
patrol goals are the graph's vertices, visited by the whole team over and over.

Nothing here is modified after construction except the cache (under its lock), so planners in
different threads can use one grid at once.
"""
import math
import threading
from collections import OrderedDict

import numpy as np

from .plan_store import PlanStore, graph_key


def symmetric_csr(src, dst, weight, n):
    """n x n CSR matrix holding every edge (src, dst, weight) in both directions."""
    from scipy.sparse import csr_matrix
    g = csr_matrix((np.concatenate([weight, weight]),
                    (np.concatenate([src, dst]), np.concatenate([dst, src]))), shape=(n, n))
    g.sort_indices()
    return g


def edge_cost(length, cost_a, cost_b):
    """Weight of the edge of ``length`` metres between cells of costs ``cost_a`` and
    ``cost_b`` (numbers or arrays): the one formula of the cell graph, its windows and the
    planner's path costs, so that they agree to the last bit."""
    return length * 0.5 * (cost_a + cost_b)


def window_cells(w, i0, j0, i1, j1):
    """Grid cell indices (grid width ``w``) of the window [i0, i1) x [j0, j1), row-major,
    i.e. in the order of its window index."""
    return (np.arange(j0, j1)[:, None] * w + np.arange(i0, i1)[None, :]).ravel()


def embed_field(cells, dist, pred, full_d, full_p):
    """Write a search over the window ``cells`` (dist and pred by window index; preds outside
    [0, len(cells)) are roots or a virtual source) into the whole-grid arrays ``full_d`` and
    ``full_p``, in place: preds become grid indices, an unreached cell gets pred -9999, and a
    cell whose pred is a root or the virtual source keeps the pred it had. Returns them."""
    full_d[cells] = dist
    inner = (pred >= 0) & (pred < len(cells))
    full_p[cells[inner]] = cells[pred[inner]]
    full_p[cells[~np.isfinite(dist)]] = -9999
    return full_d, full_p


#: the 8 neighbour offsets (dj, di) in the order of their cell index (a CSR row's order)
NEIGHBOURS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


def window_graph(grid, blocked, i0, j0, i1, j1):
    """CSR graph of the cells [i0, i1) x [j0, j1) of ``grid`` (a :class:`PlannerGrid`) without
    the cells of the boolean mask ``blocked``, indexed by window cell (row-major): the edges of
    ``grid.free_graph`` with both ends in the window and neither blocked, with the same
    weights, in the same order within each row, plus infinite-weight placeholders (a
    self-loop) where a cell has no such edge, so every row has 8 entries.

    Built from 2-D slices, one per neighbour offset, so its cost grows with the window's area
    only (cutting the edges out of the whole graph cost 1.6-2x more on cumberland's and
    broughton's windows); Dijkstra's results are the same, as a placeholder never shortens a
    distance and the real edges are relaxed in the same order."""
    from scipy.sparse import csr_matrix
    ww, wh = i1 - i0, j1 - j0
    n = ww * wh
    # one-cell frame around the window (False outside the grid) for the neighbour slices
    i0f, j0f, i1f, j1f = max(0, i0 - 1), max(0, j0 - 1), min(grid.w, i1 + 1), min(grid.h, j1 + 1)
    ok = np.zeros((wh + 2, ww + 2), dtype=bool)
    ok[1 + j0f - j0:wh + 1 + j1f - j1, 1 + i0f - i0:ww + 1 + i1f - i1] = \
        ~grid.lethal[j0f:j1f, i0f:i1f]
    inside = np.zeros_like(ok)
    inside[1:-1, 1:-1] = True
    cost = np.ones((wh + 2, ww + 2))
    cost[1 + j0f - j0:wh + 1 + j1f - j1, 1 + i0f - i0:ww + 1 + i1f - i1] = \
        grid.cost[j0f:j1f, i0f:i1f]
    free = ok & inside
    free[1:-1, 1:-1] &= ~blocked[j0:j1, i0:i1]
    here = (slice(1, wh + 1), slice(1, ww + 1))
    local = np.arange(n, dtype=np.int32).reshape(wh, ww)
    data = np.empty((wh, ww, 8))
    indices = np.empty((wh, ww, 8), dtype=np.int32)
    for k, (dj, di) in enumerate(NEIGHBOURS):
        there = (slice(1 + dj, wh + 1 + dj), slice(1 + di, ww + 1 + di))
        edge = free[here] & free[there]
        if di and dj:       # no corner cutting past a forbidden (static) cell
            edge &= ok[1 + dj:wh + 1 + dj, 1:ww + 1] & ok[1:wh + 1, 1 + di:ww + 1 + di]
        length = math.hypot(di, dj) * grid.res
        data[:, :, k] = np.where(edge, edge_cost(length, cost[here], cost[there]), np.inf)
        indices[:, :, k] = np.where(edge, local + (dj * ww + di), local)
    g = csr_matrix((data.ravel(), indices.ravel(), np.arange(0, 8 * n + 1, 8)), shape=(n, n))
    return g


def box_field(grid, obstacles, s, g, free_dist, free_pred):
    """Navigation function to cell ``g`` with the temporary ``obstacles`` (a boolean mask) in
    the box around them and the start cell ``s``, continued outside the box by the
    obstacle-free field (``free_dist``, ``free_pred``): (dist, pred, (i0, j0, i1, j1)), or
    None when there are no obstacles or the box would cover more than a quarter of the grid.
    With ``free_pred`` None, ``free_dist`` need only be a lower bound of the obstacle-free
    cost to ``g``: the field then ends at the border (dist inf and pred -9999 outside the
    box, pred -9999 at a border cell reached from the virtual source), so only paths that
    reach ``g`` inside the box can be walked, and those are optimal.

    Any path from a box cell either reaches ``g`` inside the box or leaves it through a border
    cell ``b``, costing at least ``d_box(x, b) + free_dist[b]``. One Dijkstra in the box from a
    virtual source linked to each open border cell with cost ``free_dist[b]`` (and to ``g``
    with 0) gives the least of these bounds in every box cell: its dist is a lower bound of
    the cost with the obstacles, exact where the path it leads to (box predecessors to a
    border cell, then the obstacle-free ones) costs that much (the caller checks), and inf
    only where no path exists at all. A border cell keeps its obstacle-free predecessor."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra
    w, h = grid.w, grid.h
    oj, oi = np.nonzero(obstacles)
    if not len(oi):
        return None
    si, sj = s % w, s // w
    i0, i1 = max(0, min(oi.min(), si) - 2), min(w, max(oi.max(), si) + 3)
    j0, j1 = max(0, min(oj.min(), sj) - 2), min(h, max(oj.max(), sj) + 3)
    ww, wh = i1 - i0, j1 - j0
    n = ww * wh
    if 4 * n > w * h:
        return None
    box = window_graph(grid, obstacles, i0, j0, i1, j1)
    cells = window_cells(w, i0, j0, i1, j1)
    ring = np.zeros((wh, ww), dtype=bool)
    ring[[0, -1], :] = ring[:, [0, -1]] = True
    src = np.flatnonzero(ring.ravel() | (cells == g))
    src = src[~obstacles.ravel()[cells[src]]]
    offset = free_dist[cells[src]].astype(np.float64) + 1.0    # (an explicit 0 is no edge)
    src, offset = src[np.isfinite(offset)], offset[np.isfinite(offset)]
    graph = csr_matrix((np.concatenate([box.data, offset]),
                        np.concatenate([box.indices, src.astype(np.int32)]),
                        np.concatenate([box.indptr, [box.indptr[-1] + len(src)]])),
                       shape=(n + 1, n + 1))
    dist, pred = dijkstra(graph, directed=True, indices=n, return_predecessors=True)
    dist, pred = dist[:n] - 1.0, pred[:n]
    if free_pred is None:
        full_d = np.full(w * h, np.inf, dtype=np.float32)
        full_p = np.full(w * h, -9999, dtype=np.int32)
    else:
        full_d, full_p = free_dist.copy(), free_pred.copy()
    return embed_field(cells, dist, pred, full_d, full_p) + ((i0, j0, i1, j1),)


class NavFunctionCache:
    """Goal cell index -> (dist float32, pred int32) of obstacle-free Dijkstra runs; LRU,
    at most ``cache_bytes`` (each entry costs 8 bytes per grid cell) but room for at least
    ``min_entries`` (a patrol graph's vertex count: with fewer, goals evict each other and
    every goal change costs a search); thread-safe."""

    def __init__(self, cells, cache_bytes, min_entries=0):
        self.capacity = max(max(0, int(cache_bytes)) // max(1, cells * 8), int(min_entries))
        self._d = OrderedDict()
        self._lock = threading.Lock()
        self.hits = self.misses = 0

    def __len__(self):
        return len(self._d)

    def __contains__(self, goal):
        with self._lock:
            return goal in self._d

    def get(self, goal):
        with self._lock:
            field = self._d.get(goal)
            if field is None:
                self.misses += 1
                return None
            self._d.move_to_end(goal)
            self.hits += 1
            return field

    def put(self, goal, field):
        if self.capacity <= 0:
            return
        with self._lock:
            self._d[goal] = field
            self._d.move_to_end(goal)
            while len(self._d) > self.capacity:
                self._d.popitem(last=False)

    def nbytes(self):
        with self._lock:
            return sum(d.nbytes + p.nbytes for d, p in self._d.values())

    def clear(self):
        """Forget every cached function (the counters stay)."""
        with self._lock:
            self._d.clear()


def planner_shape(width, height, map_resolution, resolution=0.1):
    """(k, columns, rows) of the planner grid of a ``width`` x ``height``-cell map: one
    planner cell per k x k map cells, k = ``resolution`` / ``map_resolution`` rounded (at
    least 1). What the planner's memory depends on (docs/navigation.md)."""
    k = max(1, int(round(resolution / map_resolution)))
    return k, (width + k - 1) // k, (height + k - 1) // k


class PlannerGrid:
    """Cost grid and obstacle-free graph of ``omap`` for the given planner parameters (see
    :mod:`spqrel_nav_lite.planner` for what they mean)."""

    def __init__(self, omap, robot_radius=0.225, inflation_radius=0.66, resolution=0.1,
                 cost_scaling=3.0, cost_weight=4.0, cache_bytes=32 << 20, cache_min_entries=0,
                 store_root=None, store_bytes=4 << 30):
        if resolution <= 0:
            raise ValueError(f"planner resolution must be positive, got {resolution}")
        self.map = omap
        k, self.w, self.h = planner_shape(omap.width, omap.height, omap.resolution,
                                          resolution)
        self.k = k
        self.res = omap.resolution * k
        self.origin = omap.origin[:2]
        self.robot_radius = float(robot_radius)
        self.inflation_radius = float(inflation_radius)
        clear = omap.clearance
        rows = np.minimum(np.arange(self.h) * k + k // 2, omap.height - 1)
        cols = np.minimum(np.arange(self.w) * k + k // 2, omap.width - 1)
        self.clear = clear[np.ix_(rows, cols)].astype(np.float64)
        self.lethal = self.clear < self.robot_radius
        d = self.clear - self.robot_radius
        self.cost = np.where(d < self.inflation_radius,
                             1.0 + cost_weight * np.exp(-cost_scaling * np.maximum(d, 0.0)), 1.0)
        n = self.h * self.w
        self.free_graph = symmetric_csr(*self._edges(), n)
        # source cell of every stored entry of free_graph (to block edges by cell)
        self.graph_rows = np.repeat(np.arange(n, dtype=np.int32), np.diff(self.free_graph.indptr))
        self.cache = NavFunctionCache(n, cache_bytes, cache_min_entries)
        self.store = None
        if store_root:
            desc = (f"map {omap.yaml_path or '(from a topic)'}\n"
                    f"grid {self.w} x {self.h} cells of {self.res} m, origin {self.origin}\n"
                    f"robot_radius {self.robot_radius}, inflation_radius "
                    f"{self.inflation_radius}, cost_scaling {cost_scaling}, cost_weight "
                    f"{cost_weight}\n")
            self.store = PlanStore(store_root, graph_key(self.w, self.h, self.res, self.origin,
                                                         self.free_graph),
                                   n, store_bytes, description=desc)

    def _edges(self):
        """(src, dst, weight) of every edge of the cell graph, once (one direction)."""
        h, w = self.h, self.w
        idx = np.arange(h * w).reshape(h, w)
        ok = ~self.lethal
        src, dst, wt = [], [], []
        for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):     # (col, row) offsets
            length = math.hypot(di, dj) * self.res
            j0, j1 = max(0, -dj), h - max(0, dj)
            i0, i1 = max(0, -di), w - max(0, di)
            a = idx[j0:j1, i0:i1]
            b = idx[j0 + dj:j1 + dj, i0 + di:i1 + di]
            m = ok[j0:j1, i0:i1] & ok[j0 + dj:j1 + dj, i0 + di:i1 + di]
            if di and dj:   # no corner cutting past a forbidden cell
                m &= ok[j0 + dj:j1 + dj, i0:i1] & ok[j0:j1, i0 + di:i1 + di]
            ca = self.cost[j0:j1, i0:i1][m]
            cb = self.cost[j0 + dj:j1 + dj, i0 + di:i1 + di][m]
            src.append(a[m])
            dst.append(b[m])
            wt.append(edge_cost(length, ca, cb))
        return (np.concatenate(src).astype(np.int32), np.concatenate(dst).astype(np.int32),
                np.concatenate(wt))

    def free_navigation_function(self, g):
        """(dist, pred, searched) of the obstacle-free Dijkstra from cell ``g``: from the
        cache when any robot sharing this grid searched it before, or from the plan store
        (:mod:`~spqrel_nav_lite.plan_store`) when any process did (``searched`` False). The
        arrays are shared: callers must not write into them (stored ones are read-only)."""
        field = self.cache.get(g)
        if field is not None:
            return field[0], field[1], False
        if self.store is not None:
            field = self.store.load(g)
            if field is not None:
                self.cache.put(g, field)
                return field[0], field[1], False
        from scipy.sparse.csgraph import dijkstra
        dist, pred = dijkstra(self.free_graph, directed=True, indices=g,
                              return_predecessors=True)
        field = (dist.astype(np.float32), pred.astype(np.int32))
        if self.store is not None:
            self.store.save(g, *field)
        self.cache.put(g, field)
        return field[0], field[1], True

    def nbytes(self):
        """Bytes of the shared arrays (without the cache)."""
        g = self.free_graph
        return sum(a.nbytes for a in (self.clear, self.lethal, self.cost, self.graph_rows,
                                      g.data, g.indices, g.indptr))
