"""Automatic patrol-graph extraction from an occupancy grid (map_server map).

Pipeline (see docs/graph_extraction.md for the choices and the measured results):

1. **Usable space**: free cells whose clearance (distance to the nearest occupied, unknown or
   off-map cell, :attr:`OccupancyMap.clearance`) is at least ``robot_radius + margin`` --
   where the robot's centre can stand. Its 8-connected pieces are found; pieces smaller than
   a robot footprint are noise, pieces outside the building and pockets are set aside
   (:func:`select_pieces`). If more than one piece remains the free space is disconnected:
   :func:`extract_graph` fails with one line naming the pieces (area, centre in metres),
   unless ``largest=True``, which keeps the largest piece. Set-aside pieces are listed in
   ``ExtractionResult.dropped``.
2. **Skeleton**: scikit-image's ``skeletonize`` of the usable piece (holes under 1 m2 --
   specks of sensor noise -- filled first, so they do not create loops).
3. **Spur pruning**: the skeleton is split into branches between junctions and end points. A
   dead-end branch is dropped when it reaches less than ``min_dead_end`` metres beyond the
   free disc around its junction (``branch length - clearance at the junction``): that removes
   the branches the medial axis grows into room corners and wall bumps, and keeps dead-end
   corridors and rooms behind doors. One pass over the original skeleton, then the pixel graph
   is rebuilt.
4. **Vertices**: junctions (a cluster of junction pixels, or junctions joined by a branch
   shorter than the merge distance max(2 clearance, spacing / 3), is one vertex), dead ends,
   and points every ``spacing`` metres (equally spaced along each branch,
   ``round(length / spacing)`` pieces). Then vertices joined by an edge shorter than half the
   merge distance are merged, loops shorter than three merge distances dropped, and dead ends
   closer than it to their neighbour removed.
5. **Edges** join consecutive vertices of a branch. The cost is the length of the shortest
   collision-free path between the two vertices in the usable space: an 8-connected
   geometric shortest path (scikit-image ``MCP_Geometric``) shortened by string pulling (each
   point joined to the farthest later point visible through usable cells), in pixels as the
   ``.graph`` format wants, rounded to an integer.

Everything is deterministic: no random numbers, ties broken by pixel order.
"""
import math
import os
from dataclasses import dataclass, field
from typing import List, Tuple

import networkx as nx
import numpy as np
from scipy import ndimage

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.extraction.cleanup import contract_short, drop_stub_ends, renumber
from patrolling_sim.extraction.free_paths import shortest_path
from patrolling_sim.extraction.skeleton import (merge_close_nodes, path_length, split_branches,
                                                pixel_graph, prune)
from patrolling_sim.extraction.space import describe_piece, free_pieces, select_pieces, usable_space
from patrolling_sim.model.graph import DIRECTIONS
from patrolling_sim.startpos.initial_poses import ROBOT_RADIUS
from spqrel_nav_lite.mapio import FREE, load_map, read_image

#: default extra clearance (m) on top of the robot radius
DEFAULT_MARGIN = 0.1
#: default distance (m) between vertices along a corridor; the shipped graphs' mean edge
#: length is 3.0-5.7 m (8 m on the coarse 'example'), see docs/graph_extraction.md
DEFAULT_SPACING = 4.0
#: default minimum reach (m) of a dead-end branch beyond the free disc at its junction
DEFAULT_MIN_DEAD_END = 1.0


@dataclass
class ExtractionParams:
    robot_radius: float = ROBOT_RADIUS
    margin: float = DEFAULT_MARGIN
    spacing: float = DEFAULT_SPACING
    min_dead_end: float = DEFAULT_MIN_DEAD_END
    largest: bool = False

    def validate(self):
        if not (self.spacing > 0 and math.isfinite(self.spacing)):
            raise PatrolInputError(f"argument --spacing: must be > 0 metres, got {self.spacing:g}")
        if not (self.min_dead_end >= 0 and math.isfinite(self.min_dead_end)):
            raise PatrolInputError(
                f"argument --min-dead-end: must be >= 0 metres, got {self.min_dead_end:g}")
        if not (self.robot_radius > 0 and math.isfinite(self.robot_radius)):
            raise PatrolInputError(
                f"argument --robot-radius: must be > 0 metres, got {self.robot_radius:g}")
        if not (self.margin >= 0 and math.isfinite(self.margin)):
            raise PatrolInputError(f"argument --margin: must be >= 0 metres, got {self.margin:g}")
        return self

    @property
    def clearance(self):
        return self.robot_radius + self.margin


@dataclass
class ExtractionResult:
    graph: nx.MultiDiGraph
    usable: np.ndarray                    # (h, w) bool, row 0 = bottom: the kept piece
    skeleton: np.ndarray                  # (h, w) bool, pruned skeleton
    dropped: List[Tuple[float, float, float]] = field(default_factory=list)  # area, x, y
    edge_paths: dict = field(default_factory=dict)  # (u, w) -> [(col, row), ...] pulled path


def direction(dx, dy):
    """Compass direction of a vector in pixel coordinates (y up): N, NE, E, ..."""
    ang = math.degrees(math.atan2(dx, dy)) % 360.0     # 0 = N, 90 = E
    return DIRECTIONS[int((ang + 22.5) // 45) % 8]


# ----------------------------------------------------------------------------- extraction
def extract_graph(occ, params=None, name="extracted"):
    """Extract a patrol graph from an :class:`~spqrel_nav_lite.mapio.OccupancyMap`.

    Returns:
        :class:`ExtractionResult` whose ``graph`` is a MultiDiGraph as
        :func:`patrolling_sim.model.graph.parse_graph` builds it (header = the map's size,
        resolution and origin).

    Raises:
        PatrolInputError: one line: no free cell, no space wide enough for the robot,
            disconnected free space (unless ``params.largest``), bad parameters.
    """
    from skimage.morphology import remove_small_holes, skeletonize
    p = (params or ExtractionParams()).validate()
    res = occ.resolution
    usable, dropped = _usable_piece(occ, p, occ.yaml_path or name)
    hole_cells = max(4, int(round((1.0 / res) ** 2)))      # specks under 1 m2
    filled = remove_small_holes(usable, area_threshold=hole_cells)
    skel = skeletonize(filled)
    if skel.sum() == 0:           # a piece a few cells wide: its centre
        cy, cx = [int(round(v)) for v in ndimage.center_of_mass(usable)]
        skel[cy, cx] = True
    clear_px = occ.clearance / res
    skel = prune(skel, clear_px, p.min_dead_end / res)
    vert_px, edges = _skeleton_vertices(skel, usable, clear_px, p, res)
    graph, edge_paths = _patrol_graph(occ, name, usable, vert_px, edges)
    return ExtractionResult(graph, usable, skel, dropped, edge_paths)


def _usable_piece(occ, p, where):
    """Step 1 of the pipeline: the piece of usable space to extract from.

    Args:
        occ: the occupancy map; p: validated :class:`ExtractionParams`; where: the map's
            name in error messages.

    Returns:
        (usable, dropped): the kept piece as an (h, w) bool mask, and the set-aside pieces as
        (area m2, x, y), the smaller selected pieces (``p.largest``) before the ignored ones.

    Raises:
        PatrolInputError: no free cell, no piece wide enough for the robot, or more than one
            selected piece without ``p.largest``.
    """
    res = occ.resolution
    if not (occ.data == FREE).any():
        raise PatrolInputError(f"{where}: the map has no free cell (nothing to patrol)")
    usable_all = usable_space(occ, p.clearance)
    footprint = math.pi * p.clearance ** 2 / res ** 2
    lab, pieces = free_pieces(usable_all, max(4, int(footprint)))
    if not pieces:
        raise PatrolInputError(
            f"{where}: no free space is wide enough for the robot (clearance "
            f"{p.clearance:.3f} m = radius {p.robot_radius:g} + margin {p.margin:g})")
    pieces, ignored = select_pieces(occ, lab, pieces)
    dropped = [describe_piece(lab, k, occ) for k in pieces[1:]]
    if dropped and not p.largest:
        desc = "; ".join(f"{a:.1f} m2 around ({x:.1f}, {y:.1f})"
                         for a, x, y in [describe_piece(lab, k, occ) for k in pieces])
        raise PatrolInputError(
            f"{where}: the robot-usable free space is in {len(pieces)} disconnected pieces "
            f"({desc}); use --largest to extract the largest one")
    dropped += [describe_piece(lab, k, occ) for k in ignored]
    return lab == pieces[0], dropped


def _skeleton_vertices(skel, usable, clear_px, p, res):
    """Step 4 of the pipeline: the vertices on the pruned skeleton ``skel`` and the edges
    joining them along its branches.

    Args:
        skel, usable: (h, w) bool masks; clear_px: the map's clearance in pixels; p:
            validated :class:`ExtractionParams`; res: metres per pixel.

    Returns:
        (vert_px, edges): vertex pixels (row, col), every one in ``usable``, and edges
        (u, w, approximate length in pixels) with u < w, possibly repeated, after merging
        close vertices and dropping short loops and stub ends.
    """
    P = pixel_graph(skel)
    if P.number_of_nodes() == 0:
        rows, cols = np.nonzero(usable)
        P.add_node((int(rows[0]), int(cols[0])))
    nodes, branches = split_branches(P)
    merge_px = max(2 * p.clearance, p.spacing / 3) / res
    groups = merge_close_nodes(P, nodes, branches, merge_px)
    # group gi is vertex gi, at its member with the largest clearance (first in pixel order)
    vert_px = [max(g, key=lambda q: (clear_px[q], -q[0], -q[1])) for g in groups]
    edges = _branch_edges(branches, groups, vert_px, merge_px, p.spacing / res)
    vert_px, edges = contract_short(vert_px, edges, merge_px / 2, clear_px)
    vert_px, edges = drop_stub_ends(vert_px, edges, merge_px)
    # snap vertices that fell on a filled hole back into usable space
    if (~usable[tuple(np.array(vert_px).T)]).any():
        _, (ir, ic) = ndimage.distance_transform_edt(~usable, return_indices=True)
        vert_px = [q if usable[q] else (int(ir[q]), int(ic[q])) for q in vert_px]
    return vert_px, edges


def _branch_edges(branches, groups, vert_px, merge_px, spacing_px):
    """Split every skeleton branch between vertex groups into ``round(length / spacing_px)``
    equal pieces (at least 1; 3 for a loop), appending the intermediate vertices' pixels to
    ``vert_px`` (group gi is vertex gi). A branch from a group back to itself shorter than
    ``3 merge_px`` is skipped. Returns the edges (u, w, piece length in pixels), u < w, in
    branch order."""
    group_of = {q: gi for gi, g in enumerate(groups) for q in g}
    edges = []
    for br in branches:
        ga, gb = group_of[br[0]], group_of[br[-1]]
        L = path_length(br)
        if ga == gb and L < 3 * merge_px:
            continue            # a link inside a junction cluster, a small loop
        pieces_n = max(1, int(round(L / spacing_px)))
        if ga == gb:
            pieces_n = max(pieces_n, 3)     # a loop needs two intermediate vertices
        cum = np.concatenate([[0.0], np.cumsum([math.hypot(a[0] - b[0], a[1] - b[1])
                                               for a, b in zip(br, br[1:])])])
        chain = [ga]
        for k in range(1, pieces_n):
            i = int(np.searchsorted(cum, L * k / pieces_n))
            q = br[min(i, len(br) - 1)]
            chain.append(len(vert_px))
            vert_px.append(q)
        chain.append(gb)
        for u, w in zip(chain, chain[1:]):
            if u != w:
                edges.append((min(u, w), max(u, w), L / pieces_n))
    return edges


def _patrol_graph(occ, name, usable, vert_px, edges):
    """Step 5 of the pipeline: the patrol graph on ``vert_px`` with one edge per vertex pair
    of ``edges`` whose vertices a collision-free path in ``usable`` joins, costed by its
    length in pixels (rounded, at least 1).

    Returns:
        (graph, edge_paths): the MultiDiGraph (header from ``occ`` and ``name``, vertices
        numbered top-left first, each vertex's arcs in neighbour order) and the pulled path
        [(col, row), ...] of each arc (u, w) in the new numbering.
    """
    res = occ.resolution
    best_edges = {}
    for u, w, approx in edges:
        if (u, w) not in best_edges:
            best_edges[(u, w)] = approx
    G = nx.MultiDiGraph(name=name, path=occ.yaml_path or name, width_px=occ.width,
                        height_px=occ.height, resolution=res, offset_x=occ.origin[0],
                        offset_y=occ.origin[1])
    for v, (r, c) in enumerate(vert_px):
        G.add_node(v, x_px=int(c), y_px=int(r), pos=(c * res + occ.origin[0],
                                                     r * res + occ.origin[1]))
    edge_paths = {}
    adj = {v: [] for v in range(len(vert_px))}
    for (u, w), approx in sorted(best_edges.items()):
        a, b = vert_px[u], vert_px[w]
        length, path = shortest_path(usable, a, b)
        if path is None:
            continue
        cost = max(1, int(round(length)))
        edge_paths[(u, w)] = [(c, r) for r, c in path]
        edge_paths[(w, u)] = [(c, r) for r, c in reversed(path)]
        adj[u].append((w, cost))
        adj[w].append((u, cost))
    for v in range(len(vert_px)):
        r, c = vert_px[v]
        for w, cost in sorted(adj[v]):
            r2, c2 = vert_px[w]
            G.add_edge(v, w, direction=direction(c2 - c, r2 - r), cost_px=cost,
                       cost_m=cost * res)
    return renumber(G, edge_paths)


# ------------------------------------------------------------------------------ init-map
def init_map_yaml(image, resolution, origin=(0.0, 0.0, 0.0), out=None, force=False,
                  negate=False):
    """Write a map_server yaml for ``image`` (png/pgm/...: dark = occupied, light = free,
    as map_server's trinary mode reads it) and return its path. The image is checked by
    loading the written yaml with :func:`spqrel_nav_lite.mapio.load_map`; on any problem
    nothing is left behind.

    Raises:
        PatrolInputError: missing/undecodable image, resolution <= 0, non-finite origin,
            existing yaml without ``force``.
    """
    if not (resolution > 0 and math.isfinite(resolution)):
        raise PatrolInputError(f"argument --resolution: must be > 0 metres per pixel, "
                               f"got {resolution:g}")
    if not all(math.isfinite(v) for v in origin):
        raise PatrolInputError(f"argument --origin: must be finite numbers, got {origin}")
    if not os.path.isfile(image):
        raise PatrolInputError(f"{image}: image not found")
    read_image(image, image)
    out = out or os.path.splitext(image)[0] + ".yaml"
    if os.path.exists(out) and not force:
        raise PatrolInputError(f"argument --out: {out} exists (use --force to overwrite)")
    rel = os.path.relpath(os.path.abspath(image), os.path.dirname(os.path.abspath(out)))
    text = (f"image: {rel}\nresolution: {float(resolution)!r}\n"
            f"origin: [{float(origin[0])!r}, {float(origin[1])!r}, {float(origin[2])!r}]\n"
            f"negate: {int(bool(negate))}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    tmp = f"{out}.tmp{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    try:
        load_map(tmp)
    except PatrolInputError:
        os.remove(tmp)
        raise
    os.replace(tmp, out)
    return out
