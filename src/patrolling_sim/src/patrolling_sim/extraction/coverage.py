"""Judging a patrol graph against its map: sensing coverage and traversability.

- :func:`coverage`: the share of the robot-reachable free space that lies within a sensing
  radius (default 5 m) of at least one vertex *and* in its line of sight (the straight segment
  from the vertex crosses only free cells). The robot-reachable free space is the free space
  (8-connected) that holds the robot-usable piece chosen by
  :func:`patrolling_sim.extraction.extract.extract_graph` (same outside / pocket rules), so a
  hand-made graph and an extracted one are judged on the same cells.
- :func:`check_graph`: the acceptance checks of an extracted graph -- connected, every vertex
  on a free cell with the robot-radius clearance, every edge traversable (a collision-free
  path exists in the usable space), every cost within 2 % of that path's length (or the
  0.5 px the integer file format can be off by, whichever is larger).

Line of sight is computed by casting rays from each vertex (one every half cell at the sensing
radius, sampled every half cell), vectorised with numpy.
"""
import math

import networkx as nx
import numpy as np

from patrolling_sim.extraction.free_paths import shortest_path
from patrolling_sim.extraction.space import free_pieces, select_pieces, usable_space
from patrolling_sim.startpos.initial_poses import ROBOT_RADIUS
from spqrel_nav_lite.mapio import FREE
from scipy import ndimage

DEFAULT_SENSING_RADIUS = 5.0
COST_TOLERANCE = 0.02


def reachable_free(occ, clearance=ROBOT_RADIUS):
    """(h, w) bool mask: free cells connected (through free cells) to the main usable piece."""
    usable = usable_space(occ, clearance)
    lab, pieces = free_pieces(usable, max(4, int(math.pi * clearance ** 2 / occ.resolution ** 2)))
    free = occ.data == FREE
    if not pieces:
        return np.zeros_like(free)
    kept, _ = select_pieces(occ, lab, pieces)
    free_lab, _ = ndimage.label(free, structure=np.ones((3, 3), int))
    ids = np.unique(free_lab[lab == kept[0]])
    return np.isin(free_lab, ids[ids > 0])


def visible_cells(occ, points, radius):
    """(h, w) bool mask of free cells within ``radius`` m of, and in line of sight from, at
    least one of ``points`` ((x, y) metres)."""
    free = occ.data == FREE
    h, w = free.shape
    R = radius / occ.resolution
    n_rays = max(16, int(math.ceil(2 * math.pi * R / 0.5)))
    ang = np.arange(n_rays) * (2 * math.pi / n_rays)
    t = np.arange(0.5, R + 1e-9, 0.5)
    dr, dc = np.sin(ang)[:, None] * t[None, :], np.cos(ang)[:, None] * t[None, :]
    seen = np.zeros_like(free)
    for x, y in points:
        c0 = (x - occ.origin[0]) / occ.resolution
        r0 = (y - occ.origin[1]) / occ.resolution
        ci, ri = int(math.floor(c0)), int(math.floor(r0))
        if not (0 <= ri < h and 0 <= ci < w) or not free[ri, ci]:
            continue
        seen[ri, ci] = True
        rr = np.floor(ri + 0.5 + dr).astype(int)
        cc = np.floor(ci + 0.5 + dc).astype(int)
        inside = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
        ok = np.zeros_like(inside)
        ok[inside] = free[rr[inside], cc[inside]]
        vis = np.logical_and.accumulate(ok, axis=1)
        seen[rr[vis], cc[vis]] = True
    return seen


def coverage(occ, pgraph, radius=DEFAULT_SENSING_RADIUS, clearance=ROBOT_RADIUS):
    """Share (0..1) of the robot-reachable free space seen from the vertices (module doc)."""
    reach = reachable_free(occ, clearance)
    total = int(reach.sum())
    if total == 0:
        return 0.0
    seen = visible_cells(occ, [tuple(p) for p in pgraph.pos], radius)
    return float((seen & reach).sum()) / total


def check_graph(occ, G, clearance=ROBOT_RADIUS, path_clearance=None,
                tolerance=COST_TOLERANCE):
    """Problems of a patrol graph (list of one-line strings; empty = passes).

    Args:
        occ: the map.
        G: MultiDiGraph as :func:`patrolling_sim.model.graph.load_graph` returns.
        clearance: minimum clearance (m) of every vertex (the robot radius).
        path_clearance: clearance (m) of the space edges must be traversable in
            (default: ``clearance``).
    """
    name = G.graph.get("path", G.graph.get("name", "graph"))
    out = []
    if G.number_of_nodes() > 1 and not nx.is_weakly_connected(G):
        out.append(f"{name}: not connected ({nx.number_weakly_connected_components(G)} parts)")
    usable = usable_space(occ, path_clearance if path_clearance is not None else clearance)
    cells = {}
    for v, d in G.nodes(data=True):
        i, j = d["x_px"], d["y_px"]
        cells[v] = (j, i)
        if not (0 <= i < occ.width and 0 <= j < occ.height) or occ.data[j, i] != FREE:
            out.append(f"{name}: vertex {v} is not on a free cell")
        elif occ.clearance[j, i] < clearance - 1e-6:
            out.append(f"{name}: vertex {v} has {occ.clearance[j, i]:.3f} m clearance "
                       f"(needs {clearance:.3f} m)")
    done = set()
    for u, w, d in G.edges(data=True):
        key = (min(u, w), max(u, w))
        if key in done:
            continue
        done.add(key)
        a, b = cells[u], cells[w]
        h, wd = usable.shape
        if not all(0 <= q[0] < h and 0 <= q[1] < wd for q in (a, b)) \
                or not (usable[a] and usable[b]):
            out.append(f"{name}: edge {u}-{w}: an end is outside the usable space")
            continue
        length, path = shortest_path(usable, a, b)
        if path is None:
            out.append(f"{name}: edge {u}-{w} is not traversable by the robot")
            continue
        if abs(d["cost_px"] - length) > max(tolerance * length, 0.5):
            out.append(f"{name}: edge {u}-{w} costs {d['cost_px']} px but the shortest "
                       f"collision-free path is {length:.1f} px")
    return out
