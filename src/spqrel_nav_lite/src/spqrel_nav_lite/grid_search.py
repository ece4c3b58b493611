"""A* over the planner's cell grid, in C++ (``csrc/grid_astar.cpp``, built by catkin into the
workspace's ``lib`` folder as ``libspqrel_nav_grid.so``), called through ctypes.

The planner uses it for the searches around temporary obstacles that its small box search
cannot settle, guided by the goal's obstacle-free navigation function (docs/navigation.md,
"Planning around other robots"). Without the built library (the pure-Python unit tests can
run before ``catkin_make``) :func:`load` returns None and the planner keeps its scipy
searches; the results are optimal either way.

The library is looked for, in this order, in ``$SPQREL_NAV_GRID_LIB`` (a file), the folders
of ``$LD_LIBRARY_PATH`` (``devel/setup.bash`` puts the workspace's ``lib`` there), the
``lib`` folders of ``$CMAKE_PREFIX_PATH``, and this source tree's workspace (``devel/lib``,
``install/lib``).
"""
import ctypes
import math
import os
import threading

import numpy as np

LIBRARY = "libspqrel_nav_grid.so"

_lock = threading.Lock()
_lib = None
_tried = False


def _candidates():
    env = os.environ.get("SPQREL_NAV_GRID_LIB")
    if env:
        yield env
    dirs = [d for d in os.environ.get("LD_LIBRARY_PATH", "").split(os.pathsep) if d]
    dirs += [os.path.join(p, "lib") for p in
             os.environ.get("CMAKE_PREFIX_PATH", "").split(os.pathsep) if p]
    # <workspace>/src/spqrel_nav_lite/src/spqrel_nav_lite/grid_search.py
    ws = os.path.abspath(os.path.join(os.path.dirname(__file__), *[os.pardir] * 4))
    dirs += [os.path.join(ws, "devel", "lib"), os.path.join(ws, "install", "lib")]
    for d in dirs:
        yield os.path.join(d, LIBRARY)


def load():
    """The ctypes library, or None if it is not built (then one search per process for it)."""
    global _lib, _tried
    with _lock:
        if _tried:
            return _lib
        _tried = True
        for path in _candidates():
            if not os.path.isfile(path):
                continue
            lib = ctypes.CDLL(path)         # CDLL: the GIL is released during calls
            f = lib.spqrel_grid_astar
            f.restype = ctypes.c_int64
            f.argtypes = [ctypes.c_int64, ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p,
                          ctypes.c_void_p, ctypes.c_void_p, ctypes.c_double, ctypes.c_double,
                          ctypes.c_int64, ctypes.c_int64, ctypes.c_void_p, ctypes.c_int64,
                          ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int64)]
            _lib = lib
            break
        return _lib


def _c_array(a, dtype):
    a = np.asarray(a)
    if a.dtype == np.bool_ and dtype == np.uint8 and a.flags.c_contiguous:
        a = a.view(np.uint8)            # the same bytes, no copy
    a = np.ascontiguousarray(a, dtype=dtype)
    return a, a.ctypes.data


def astar(lethal, obstacles, cost, heur, res, s, g):
    """Optimal path from cell ``s`` to cell ``g`` (flat indices of the ``h x w`` grid).

    Args:
        lethal, obstacles: boolean ``(h, w)`` masks of forbidden cells (lethal cells also
            forbid the diagonal moves that pass them, as in the planner's cell graph).
        cost: ``(h, w)`` cell costs (>= 1); the edge weight between neighbours is
            ``length * 0.5 * (cost_a + cost_b)`` (planner_grid.edge_cost), ``length`` being
            ``res`` or ``res * sqrt(2)``.
        heur: ``(h * w,)`` consistent lower bound of the cost to ``g`` (the goal's
            obstacle-free navigation function, or a bound of it), inf where ``g`` cannot be
            reached.

    Returns:
        (cells, cost, expanded): the path's cell indices from ``s`` to ``g`` (int64 array)
        and its cost, or (None, inf, expanded) if ``g`` cannot be reached. Among equally
        cheap paths it is the one a Dijkstra field from ``g`` gives (each cell linked to its
        neighbour nearest ``g``: the path leaves an obstacle-free path as early as it can);
        ``expanded`` counts the cells of both searches (csrc/grid_astar.cpp).

    Raises:
        RuntimeError: the library is not built (see :func:`load`), or bad arguments.
    """
    lib = load()
    if lib is None:
        raise RuntimeError(f"spqrel_nav_lite: {LIBRARY} is not built (run catkin_make)")
    h, w = lethal.shape
    lethal, p_lethal = _c_array(lethal, np.uint8)
    obstacles, p_obst = _c_array(obstacles, np.uint8)
    cost, p_cost = _c_array(cost, np.float64)
    heur, p_heur = _c_array(heur, np.float32)
    if obstacles.shape != (h, w) or cost.shape != (h, w) or heur.size != h * w:
        raise RuntimeError("grid_search.astar: lethal, obstacles, cost and heur must match "
                           f"the {h} x {w} grid")
    path = np.empty(h * w, dtype=np.int32)
    out_cost, expanded = ctypes.c_double(), ctypes.c_int64()
    n = lib.spqrel_grid_astar(w, h, p_lethal, p_obst, p_cost, p_heur, float(res),
                              math.hypot(1, 1) * res, int(s), int(g), path.ctypes.data,
                              path.size, ctypes.byref(out_cost), ctypes.byref(expanded))
    if n < 0:
        raise RuntimeError(f"grid_search.astar: error {n} (cells {s} -> {g} on {h} x {w})")
    if n == 0:
        return None, math.inf, expanded.value
    return path[:n].astype(np.int64), out_cost.value, expanded.value
