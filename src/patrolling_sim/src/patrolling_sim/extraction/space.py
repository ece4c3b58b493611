"""Graph extraction, step 1: the usable free space (docs/graph_extraction.md).

Where the robot's centre can stand (free cells with enough clearance), its 8-connected
pieces, and which pieces are set aside: outside the building, pockets. Used by
:mod:`patrolling_sim.extraction.extract` and :mod:`patrolling_sim.extraction.coverage`.
"""
import numpy as np

from spqrel_nav_lite.mapio import FREE
from scipy import ndimage

#: usable pieces smaller than this share of the largest one are pockets, not places to patrol
POCKET_SHARE = 0.1


def usable_space(occ, clearance):
    """Boolean (h, w) mask of cells where the robot centre fits (row 0 = bottom)."""
    return (occ.data == FREE) & (occ.clearance >= clearance)


def free_pieces(mask, min_cells):
    """Labels of the 8-connected pieces of ``mask`` with at least ``min_cells`` cells,
    largest first (ties: lowest label)."""
    lab, n = ndimage.label(mask, structure=np.ones((3, 3), int))
    if n == 0:
        return lab, []
    sizes = np.bincount(lab.ravel())[1:]
    keep = [i + 1 for i in np.argsort(-sizes, kind="stable") if sizes[i] >= min_cells]
    return lab, keep


def select_pieces(occ, lab, pieces):
    """Split the pieces into (kept, ignored), kept largest first.

    Ignored: pieces *outside the building* -- their free-space component touches the image
    border, or their outline encloses another piece at least half their size (a ring of free
    space drawn around the walls) -- as long as some piece is not outside; then *pockets*:
    pieces under ``POCKET_SHARE`` of the largest remaining one (closets, gaps behind
    furniture, specks).
    """
    free_lab, _ = ndimage.label(occ.data == FREE, structure=np.ones((3, 3), int))
    border = set(np.unique(np.concatenate([free_lab[0], free_lab[-1], free_lab[:, 0],
                                           free_lab[:, -1]]))) - {0}
    outside = []
    for k in pieces:
        mask = lab == k
        r, c = np.argwhere(mask)[0]
        if free_lab[r, c] in border:
            outside.append(k)
            continue
        holes = ndimage.binary_fill_holes(mask) & ~mask
        if any((holes & (lab == j)).any() and (lab == j).sum() >= mask.sum() / 2
               for j in pieces if j != k):
            outside.append(k)
    inside = [k for k in pieces if k not in outside]
    if not inside:
        inside, outside = pieces, []
    sizes = {k: int((lab == k).sum()) for k in inside}
    big = max(sizes.values())
    kept = [k for k in inside if sizes[k] >= POCKET_SHARE * big]
    return kept, [k for k in pieces if k not in kept]


def describe_piece(lab, k, occ):
    rows, cols = np.nonzero(lab == k)
    cy, cx = ndimage.center_of_mass(lab == k)
    x, y = occ.cell_to_world(cx, cy)
    return len(rows) * occ.resolution ** 2, x, y
