"""Map-derived structures built once per process and shared, read-only, by its robots.

A ``nav_host`` process (docs/navigation.md) runs the localiser and move_base of many robots on
one map. Each of them would otherwise build its own copy of the same arrays: the map's
clearance (distance transform), the likelihood fields of the localiser and of move_base's
laser check, and the planner's cost grid and graph. :class:`SharedMaps` builds each of them on
first request, keyed by the parameters it depends on, and hands the same object to every later
request; the planner's navigation-function cache lives in the shared grid, so a goal searched
for one robot costs nothing for the others, and with a plan store
(:mod:`~spqrel_nav_lite.plan_store`) nothing for the other processes and later runs either.

Thread-safe: the first requests may come from several threads at once.
"""
import threading

from .particle_filter import LikelihoodField
from .planner_grid import PlannerGrid


class SharedMaps:
    """``cache_bytes``: bound of each planner grid's navigation-function cache (None: the
    first request's); ``cache_goals``: room for at least that many navigation functions
    whatever their size (the patrol graph's vertex count); ``store_root``: folder of the plan
    store shared with other processes (None: none), bounded by ``store_bytes``."""

    def __init__(self, omap, cache_bytes=None, cache_goals=0, store_root=None,
                 store_bytes=4 << 30):
        self.map = omap
        self.cache_bytes = cache_bytes
        self.cache_goals = int(cache_goals)
        self.store_root = store_root
        self.store_bytes = store_bytes
        self._lock = threading.Lock()
        self._fields = {}
        self._grids = {}

    def likelihood_field(self, max_dist):
        key = round(float(max_dist), 9)
        with self._lock:
            field = self._fields.get(key)
            if field is None:
                field = self._fields[key] = LikelihoodField(self.map, key)
            return field

    def planner_grid(self, robot_radius, inflation_radius, resolution, cache_bytes):
        """The grid for these parameters; its navigation-function cache is bounded by the
        process's ``cache_bytes`` if set, else by the first request's."""
        if self.cache_bytes is not None:
            cache_bytes = self.cache_bytes
        key = tuple(round(float(v), 9) for v in (robot_radius, inflation_radius, resolution))
        with self._lock:
            grid = self._grids.get(key)
            if grid is None:
                grid = self._grids[key] = PlannerGrid(
                    self.map, robot_radius=key[0], inflation_radius=key[1],
                    resolution=key[2], cache_bytes=cache_bytes,
                    cache_min_entries=self.cache_goals, store_root=self.store_root,
                    store_bytes=self.store_bytes)
            return grid

    def stats(self):
        """(likelihood fields, planner grids, cached navigation functions, cache hits,
        misses, plan-store loads, plan-store saves) so far."""
        with self._lock:
            grids = list(self._grids.values())
            stores = [g.store for g in grids if g.store is not None]
            return (len(self._fields), len(grids), sum(len(g.cache) for g in grids),
                    sum(g.cache.hits for g in grids), sum(g.cache.misses for g in grids),
                    sum(s.loads for s in stores), sum(s.saves for s in stores))
