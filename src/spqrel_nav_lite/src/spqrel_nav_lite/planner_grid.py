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


def symmetric_csr(src, dst, weight, n):
    """n x n CSR matrix holding every edge (src, dst, weight) in both directions."""
    from scipy.sparse import csr_matrix
    g = csr_matrix((np.concatenate([weight, weight]),
                    (np.concatenate([src, dst]), np.concatenate([dst, src]))), shape=(n, n))
    g.sort_indices()
    return g


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


class PlannerGrid:
    """Cost grid and obstacle-free graph of ``omap`` for the given planner parameters (see
    :mod:`spqrel_nav_lite.planner` for what they mean)."""

    def __init__(self, omap, robot_radius=0.225, inflation_radius=0.66, resolution=0.1,
                 cost_scaling=3.0, cost_weight=4.0, cache_bytes=32 << 20, cache_min_entries=0):
        if resolution <= 0:
            raise ValueError(f"planner resolution must be positive, got {resolution}")
        self.map = omap
        self.k = k = max(1, int(round(resolution / omap.resolution)))
        self.res = omap.resolution * k
        self.origin = omap.origin[:2]
        self.robot_radius = float(robot_radius)
        self.inflation_radius = float(inflation_radius)
        clear = omap.clearance
        self.h = (omap.height + k - 1) // k
        self.w = (omap.width + k - 1) // k
        rows = np.minimum(np.arange(self.h) * k + k // 2, omap.height - 1)
        cols = np.minimum(np.arange(self.w) * k + k // 2, omap.width - 1)
        self.clear = clear[np.ix_(rows, cols)].astype(np.float64)
        self.lethal = self.clear < self.robot_radius
        d = self.clear - self.robot_radius
        self.cost = np.where(d < self.inflation_radius,
                             1.0 + cost_weight * np.exp(-cost_scaling * np.maximum(d, 0.0)), 1.0)
        self._build_edges()
        n = self.h * self.w
        self.free_graph = symmetric_csr(self.src, self.dst, self.wt, n)
        # source cell of every stored entry of free_graph (to block edges by cell)
        self.graph_rows = np.repeat(np.arange(n, dtype=np.int32), np.diff(self.free_graph.indptr))
        self.cache = NavFunctionCache(n, cache_bytes, cache_min_entries)

    def _build_edges(self):
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
            wt.append(length * 0.5 * (ca + cb))
        src = np.concatenate(src).astype(np.int32)
        order = np.argsort(src, kind="stable")          # by source cell, hence by source row
        self.src = src[order]
        self.dst = np.concatenate(dst).astype(np.int32)[order]
        self.wt = np.concatenate(wt)[order]
        # edges whose source lies in rows [j0, j1): src[row_start[j0]:row_start[j1]]
        self.row_start = np.searchsorted(self.src, np.arange(h + 1) * w).astype(np.int64)

    def free_navigation_function(self, g):
        """(dist, pred, searched) of the obstacle-free Dijkstra from cell ``g``: from the
        cache when any robot sharing this grid searched it before (``searched`` False)."""
        field = self.cache.get(g)
        if field is not None:
            return field[0], field[1], False
        from scipy.sparse.csgraph import dijkstra
        dist, pred = dijkstra(self.free_graph, directed=True, indices=g,
                              return_predecessors=True)
        field = (dist.astype(np.float32), pred.astype(np.int32))
        self.cache.put(g, field)
        return field[0], field[1], True

    def nbytes(self):
        """Bytes of the shared arrays (without the cache)."""
        g = self.free_graph
        return sum(a.nbytes for a in (self.clear, self.lethal, self.cost, self.src, self.dst,
                                      self.wt, self.row_start, self.graph_rows, g.data,
                                      g.indices, g.indptr))
