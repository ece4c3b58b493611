"""Global planner: Dijkstra over a cost grid derived from the map's distance transform.

The grid is the map downsampled to ``resolution`` (cells keep the clearance of their centre).
Cells closer than ``robot_radius`` to an obstacle are forbidden; within ``robot_radius +
inflation_radius`` a soft cost (decaying exponentially with the clearance, like a costmap's
inflation layer) keeps paths away from walls. One Dijkstra run from the goal gives a navigation
function for the whole map, so re-planning from a new robot position is a cheap walk along the
predecessor tree until the obstacle set changes. Temporary obstacles (points in metres) forbid
the cells within ``robot_radius + obstacle_margin`` of them.

Patrol goals repeat (the same graph vertices over and over), so navigation functions computed
without temporary obstacles are kept in a least-recently-used cache bounded in bytes
(``cache_bytes``): a goal seen before costs no search at all while nothing is in the way.

When the obstacle-free optimum crosses a temporary obstacle, the search with obstacles first
runs in the small box around the obstacles and the robot, continued outside by the cached
obstacle-free function (``planner_grid.box_field``): its path is kept when it costs exactly the
box's lower bound, which makes it optimal. Otherwise one of the searches of
:mod:`~spqrel_nav_lite.obstacle_search` runs, exact on the whole map: an A* from the robot's
cell (``obstacle_search="astar"``, the default, with the C++ workspace built) or Dijkstra in
windows around start and goal grown until provably exact (``"window"``), which may end in a
whole-map search. A goal moved off its own cell because a robot stands there is searched with
the obstacles at once (box, then A* or window), bounded by the (cached) function of the goal's
own cell, never by a whole-map search of its own (see ``_free_bound``): the box's path must
then reach the goal inside the box.
"""
import math

import numpy as np
from scipy.sparse.csgraph import dijkstra

from . import grid_search
from .obstacle_search import path_field, window_field
from .planner_grid import PlannerGrid, box_field, edge_cost


OBSTACLE_SEARCHES = ("astar", "window")
PATH_FIELD = "astar"    # the window entry of a field from the A* (one path and its band)


class PlanningError(Exception):
    """No plan: the message is the reason (one line)."""


class GlobalPlanner:
    """Per-robot planner state (temporary obstacles, current navigation function) over a
    :class:`~spqrel_nav_lite.planner_grid.PlannerGrid`: ``grid`` shares one among the robots
    of a process (then the grid parameters here are ignored); without it one is built.
    ``obstacle_search``: "astar" (the C++ A*, if built; else as "window") or "window" (scipy's
    Dijkstra in a box or growing windows): see the module notes."""

    def __init__(self, omap, robot_radius=0.225, inflation_radius=0.66, resolution=0.1,
                 cost_scaling=3.0, cost_weight=4.0, obstacle_margin=0.1, cache_bytes=32 << 20,
                 grid=None, obstacle_search="astar"):
        if obstacle_search not in OBSTACLE_SEARCHES:
            raise ValueError(f"obstacle_search must be one of {', '.join(OBSTACLE_SEARCHES)}, "
                             f"got {obstacle_search!r}")
        if grid is None:
            grid = PlannerGrid(omap, robot_radius, inflation_radius, resolution, cost_scaling,
                               cost_weight, cache_bytes)
        self.grid = grid
        self.map = grid.map
        self.k, self.res, self.origin = grid.k, grid.res, grid.origin
        self.robot_radius = grid.robot_radius
        self.inflation_radius = grid.inflation_radius
        self.obstacle_margin = float(obstacle_margin)
        self.h, self.w = grid.h, grid.w
        self.clear, self.lethal, self.cost = grid.clear, grid.lethal, grid.cost
        self._free_graph, self._rows = grid.free_graph, grid.graph_rows
        self._graph = None
        self._obstacles = np.zeros((self.h, self.w), dtype=bool)
        self._field = None      # (goal_index, dist, pred, computed without obstacles, window)
        self._taken_goal = None  # the goal's own cell when an obstacle moved the goal off it
        self.window_searches = 0        # searches with obstacles that stayed in a window
        self.searches = 0               # Dijkstra and A* runs of this planner (statistics)
        self.astar_searches = 0         # A* runs (with obstacles)
        self.astar_expanded = 0         # cells they expanded
        self.astar = obstacle_search == "astar" and grid_search.load() is not None
        #: what searches with obstacles: for the node's log
        self.search_label = "A* (C++)" if self.astar else \
            "Dijkstra in windows (scipy)" + (f"; {grid_search.LIBRARY} not built"
                                             if obstacle_search == "astar" else "")

    @property
    def _cache(self):
        """The navigation-function cache (shared with the grid's other planners)."""
        return self.grid.cache

    # -- grid helpers -------------------------------------------------------------------
    def cell(self, x, y):
        return (int(math.floor((x - self.origin[0]) / self.res)),
                int(math.floor((y - self.origin[1]) / self.res)))

    def cell_center(self, i, j):
        return (self.origin[0] + (i + 0.5) * self.res, self.origin[1] + (j + 0.5) * self.res)

    def in_grid(self, i, j):
        return 0 <= i < self.w and 0 <= j < self.h

    def blocked_mask(self):
        return self.lethal | self._obstacles

    def _csgraph(self):
        """The cell graph for Dijkstra with the current temporary obstacles: the grid's
        obstacle-free graph (both directions stored: ``dijkstra(directed=False)`` would rebuild
        the symmetric graph on every call, at more than the cost of the search itself) with the
        edges touching obstacle cells set to infinity."""
        if self._graph is None:
            if self._obstacles.any():
                flat = self._obstacles.ravel()
                g = self._free_graph.copy()
                g.data[flat[self._rows] | flat[g.indices]] = np.inf
                self._graph = g
            else:
                self._graph = self._free_graph
        return self._graph

    # -- temporary obstacles ---------------------------------------------------------------
    def set_obstacles(self, points):
        """Replace the temporary obstacles by ``points`` ((N, 2) metres). Returns True if the
        forbidden cell set changed (the navigation function is then recomputed lazily)."""
        mask = np.zeros((self.h, self.w), dtype=bool)
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        if len(pts):
            r = self.robot_radius + self.obstacle_margin
            rc = int(math.ceil(r / self.res))
            off = np.arange(-rc, rc + 1)
            oi, oj = np.meshgrid(off, off)
            keep = np.hypot(oi, oj) * self.res <= r + 0.5 * self.res
            oi, oj = oi[keep], oj[keep]
            ci = np.floor((pts[:, 0] - self.origin[0]) / self.res).astype(int)
            cj = np.floor((pts[:, 1] - self.origin[1]) / self.res).astype(int)
            ii = (ci[:, None] + oi[None, :]).ravel()
            jj = (cj[:, None] + oj[None, :]).ravel()
            v = (ii >= 0) & (ii < self.w) & (jj >= 0) & (jj < self.h)
            mask[jj[v], ii[v]] = True
        if np.array_equal(mask, self._obstacles):
            return False
        self._obstacles = mask
        self._graph = None
        self._field = None
        return True

    def clear_obstacles(self):
        return self.set_obstacles(np.zeros((0, 2)))

    # -- planning -----------------------------------------------------------------------------
    def _nearest_open(self, i, j, max_dist, blocked):
        """Nearest non-blocked cell to (i, j) within max_dist metres, or None."""
        rc = int(math.ceil(max_dist / self.res))
        i0, i1 = max(0, i - rc), min(self.w, i + rc + 1)
        j0, j1 = max(0, j - rc), min(self.h, j + rc + 1)
        if i0 >= i1 or j0 >= j1:
            return None
        sub = ~blocked[j0:j1, i0:i1]
        jj, ii = np.nonzero(sub)
        if not len(ii):
            return None
        d = np.hypot(ii + i0 - i, jj + j0 - j)
        k = int(np.argmin(d))
        if d[k] * self.res > max_dist:
            return None
        return int(ii[k] + i0), int(jj[k] + j0)

    def check_goal(self, gx, gy, tolerance):
        """(i, j) plan cell for a goal, or PlanningError with the reason."""
        state = self.map.cell_state(gx, gy)
        if state == "out-of-map":
            raise PlanningError(f"goal ({gx:.2f}, {gy:.2f}) is outside the map")
        if state != "free":
            raise PlanningError(f"goal ({gx:.2f}, {gy:.2f}) is inside an obstacle "
                                f"({state} map cell)")
        i, j = self.cell(gx, gy)
        blocked = self.blocked_mask()
        if self.in_grid(i, j) and not blocked[j, i]:
            return i, j
        c = self._nearest_open(i, j, tolerance, blocked)
        if c is None:
            raise PlanningError(f"goal ({gx:.2f}, {gy:.2f}) is closer than the robot radius "
                                f"{self.robot_radius} m to obstacles, with no free cell within "
                                f"the goal tolerance {tolerance} m")
        return c

    def plan(self, start, goal, tolerance=0.4, start_search=1.0):
        """Path [(x, y), ...] from start to goal (metres), first point = start cell.

        Raises:
            PlanningError: goal outside the map / in an obstacle / unreachable.
        """
        gi, gj = self.check_goal(goal[0], goal[1], tolerance)
        blocked = self.blocked_mask()
        si, sj = self.cell(start[0], start[1])
        if not self.in_grid(si, sj) or blocked[sj, si]:
            c = self._nearest_open(si, sj, start_search, blocked)
            if c is None:
                raise PlanningError(f"robot at ({start[0]:.2f}, {start[1]:.2f}) is inside an "
                                    f"obstacle with no free cell within {start_search} m")
            si, sj = c
        g = gj * self.w + gi
        s = sj * self.w + si
        gi0, gj0 = self.cell(goal[0], goal[1])
        # the goal's own cell, when a temporary obstacle (a robot standing on the vertex) moved
        # the goal off it: see _free_bound
        self._taken_goal = gj0 * self.w + gi0 if g != gj0 * self.w + gi0 and \
            self.in_grid(gi0, gj0) and not self.lethal[gj0, gi0] else None
        if self._field is None or self._field[0] != g:
            if self._taken_goal is None:
                self._field = (g,) + self._navigation_function(g, free=True)
            else:
                # the goal moved because of the obstacles: search with them straight away
                self._field = (g,) + self._obstacle_field(s, g)
        cells = self._walk(s, g)
        if cells is None and not self._field[3] and self._field[4] is not None:
            # a window field from an earlier position that the robot has left: search again
            self._field = (g,) + self._obstacle_field(s, g)
            cells = self._walk(s, g)
        if cells is not None and self._obstacles.any() and self._field[3] and \
                self._obstacles.ravel()[cells].any():
            # the obstacle-free optimum crosses a temporary obstacle: search around it
            # (otherwise that path is optimal with the obstacles too: they only remove cells)
            self._field = (g,) + self._obstacle_field(s, g, free=self._field[1:3])
            cells = self._walk(s, g)
        if cells is None:
            raise PlanningError(f"no path from ({start[0]:.2f}, {start[1]:.2f}) to goal "
                                f"({goal[0]:.2f}, {goal[1]:.2f})")
        xs = self.origin[0] + (cells % self.w + 0.5) * self.res
        ys = self.origin[1] + (cells // self.w + 0.5) * self.res
        path = np.column_stack([xs, ys])
        path[-1] = goal if self.map.is_free(*goal) and not blocked[gj, gi] else path[-1]
        return path

    def _walk(self, s, g, field=None):
        """Cell indices from ``s`` to ``g`` along the current field (or ``field``: (dist,
        pred)), or None if unreachable. Every step of a field's walk lowers its value by the
        step's cost, at least the resolution, so a longer walk is not one (a local field
        entered from outside its box: see _local_field) and gives None too."""
        dist, pred = self._field[1:3] if field is None else field
        if not np.isfinite(dist[s]):
            return None
        cells = [s]
        cap = int(dist[s] / self.res) + 2
        while cells[-1] != g:
            if len(cells) > cap or pred[cells[-1]] < 0:
                return None
            cells.append(int(pred[cells[-1]]))
        return np.array(cells)

    def _path_cost(self, cells):
        """Cost of the walk ``cells`` (edge costs as in the cell graph)."""
        i, j = cells % self.w, cells // self.w
        length = np.hypot(np.diff(i), np.diff(j)) * self.res
        c = self.cost.ravel()[cells]
        return float(np.sum(edge_cost(length, c[:-1], c[1:])))

    def _navigation_function(self, g, free):
        """(dist, pred, free) of a Dijkstra run from cell index ``g``, without temporary
        obstacles if ``free`` (or if there are none). Obstacle-free fields come from the
        shared cache when this goal was searched before (by any robot on the same grid)."""
        free = free or not self._obstacles.any()
        if free:
            dist, pred, searched = self.grid.free_navigation_function(g)
            self.searches += int(searched)
            return dist, pred, True, None
        dist, pred = dijkstra(self._csgraph(), directed=True, indices=g,
                              return_predecessors=True)
        self.searches += 1
        return dist.astype(np.float32), pred.astype(np.int32), False, None

    def _obstacle_field(self, s, g, free=None):
        """(dist, pred, False, window) of the search with temporary obstacles, exact on the
        whole map (see the module notes); ``window`` is (i0, j0, i1, j1) or None for the whole
        grid. ``free``: (dist, pred) of the obstacle-free field of ``g`` if at hand."""
        if free is None and self._taken_goal is None:
            free = self._navigation_function(g, free=True)[:2]
        # a moved goal has only a lower bound: the box's path must then reach it in the box
        free_dist, free_pred = (self._free_bound(g), None) if free is None else free
        local = self._local_field(s, g, free_dist, free_pred)
        if local is not None:
            return local
        if self.astar:
            return self._path_field(s, g, free_dist)
        field, searches = window_field(self.grid, self._obstacles, s, g, free_dist)
        self.searches += searches
        if field is None:
            return self._navigation_function(g, free=False)[:3] + (None,)
        self.window_searches += 1
        full_d, full_p, window = field
        return full_d, full_p, False, window

    def _path_field(self, s, g, heur):
        """(dist, pred, False, PATH_FIELD) of the A* from ``s`` to ``g`` guided by ``heur``
        (the obstacle-free function of ``g``, or a lower bound of it): the path and its band
        (:func:`~spqrel_nav_lite.obstacle_search.path_field`)."""
        dist, pred, expanded = path_field(self.grid, self._obstacles, heur, s, g)
        self.searches += 1
        self.astar_searches += 1
        self.astar_expanded += expanded
        return dist, pred, False, PATH_FIELD

    def _local_field(self, s, g, free_dist, free_pred):
        """(dist, pred, False, box) of the search with the temporary obstacles in the box
        around them and the start, continued outside by the obstacle-free field if
        ``free_pred`` is given (:func:`~spqrel_nav_lite.planner_grid.box_field`), or None when
        its path from ``s`` is not provably optimal: the walk from ``s`` must cost exactly the
        box's bound at ``s``.
        The box is about the laser's reach around the robot, whatever the distance to the
        goal, while the window search's area grows with that distance."""
        out = box_field(self.grid, self._obstacles, s, g, free_dist, free_pred)
        if out is None:
            return None
        self.searches += 1
        full_d, full_p, box = out
        if not np.isfinite(full_d[s]):
            return full_d, full_p, False, box   # no way out of the box, nor to g: no path
        walk = self._walk(s, g, (full_d, full_p))
        if walk is None or self._obstacles.ravel()[walk].any() or \
                self._path_cost(walk) > full_d[s] * (1.0 + 1e-5) + 1e-6:
            return None
        self.window_searches += 1
        return full_d, full_p, False, box

    def _free_bound(self, g):
        """Lower bound, per cell, on the obstacle-free cost to goal cell ``g``: exact (the
        obstacle-free navigation function of ``g``) unless ``g`` is a goal moved off its own
        cell ``g0`` by a temporary obstacle. Then it is ``d0 - d0[g]`` with ``d0`` the cached
        obstacle-free function of ``g0`` (the triangle inequality on the symmetric cell graph:
        d(x, g0) <= d(x, g) + d(g, g0)). The cells a goal is moved to change with every robot
        standing near it, while the vertices themselves stay cached: the bound comes from the
        cache instead of a whole-map search of each moved goal."""
        g0 = self._taken_goal
        if g0 is not None:
            d0 = self._navigation_function(g0, free=True)[0]
            if np.isfinite(d0[g]):
                return np.maximum(d0 - d0[g], 0.0)
        return self._navigation_function(g, free=True)[0]

    def path_cost(self, start):
        """Navigation-function value (weighted metres) at a position, inf if unreachable or no
        field computed."""
        if self._field is None:
            return math.inf
        i, j = self.cell(*start)
        if not self.in_grid(i, j):
            return math.inf
        return float(self._field[1][j * self.w + i])


def path_length(path):
    p = np.asarray(path, dtype=float)
    if len(p) < 2:
        return 0.0
    return float(np.hypot(*np.diff(p, axis=0).T).sum())


def path_blocked(path, points, radius, from_index=0, horizon=None):
    """Index of the first path point (from ``from_index``, over ``horizon`` metres) that lies
    within ``radius`` of any of ``points``, or None."""
    p = np.asarray(path, dtype=float)[from_index:]
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(p) or not len(pts):
        return None
    if horizon is not None:
        seg = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        p = p[seg <= horizon]
    lo, hi = p.min(axis=0) - radius, p.max(axis=0) + radius
    pts = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
    if not len(pts):
        return None
    d2 = ((p[:, None, :] - pts[None, :, :]) ** 2).sum(axis=2)
    hit = np.nonzero((d2 <= radius * radius).any(axis=1))[0]
    return int(hit[0]) + from_index if len(hit) else None
