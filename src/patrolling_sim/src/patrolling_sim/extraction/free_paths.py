"""Graph extraction, step 5: free-path edge costs (docs/graph_extraction.md).

The length of the shortest collision-free path between two pixels of the usable space: an
8-connected geometric shortest path (scikit-image ``MCP_Geometric``) in a window that grows
until it provably holds the path, shortened by string pulling. Used by the extractor and by
:func:`patrolling_sim.extraction.coverage.check_graph`, which therefore agree.
"""
import math

import numpy as np

from patrolling_sim.extraction.skeleton import path_length


def _visible(usable, a, b):
    """True if the segment between pixel centres a=(r, c) and b lies in usable cells
    (sampled every 0.25 cell)."""
    n = int(math.ceil(max(abs(b[0] - a[0]), abs(b[1] - a[1])) * 4)) + 1
    rr = np.rint(np.linspace(a[0], b[0], n)).astype(int)
    cc = np.rint(np.linspace(a[1], b[1], n)).astype(int)
    return bool(usable[rr, cc].all())


def pull_string(usable, path):
    """Shorten a pixel path: from each kept point jump to the farthest later point it sees
    (scanning back from the end), then drop any point whose neighbours see each other."""
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not _visible(usable, path[i], path[j]):
            j -= 1
        out.append(path[j])
        i = j
    k = 1
    while k < len(out) - 1:
        if _visible(usable, out[k - 1], out[k + 1]):
            del out[k]
            k = max(1, k - 1)
        else:
            k += 1
    return out


def shortest_path(usable, a, b):
    """Shortest collision-free path between pixels a and b (row, col) through ``usable``:
    (length_px, pulled path) or (inf, None).

    The search runs in a window around a and b that grows until it provably holds the path
    (every point p of a path of length l from a to b has ``|pa| + |pb| <= l``), so the result
    depends only on ``usable`` and the pair {a, b}: the extractor and :func:`check_graph`
    agree."""
    if tuple(b) < tuple(a):
        length, path = shortest_path(usable, b, a)
        return length, (None if path is None else path[::-1])
    h, w = usable.shape
    straight = math.hypot(a[0] - b[0], a[1] - b[1])
    extra = int(max(8, straight / 2))
    while True:
        length, path = _window_path(usable, a, b, extra)
        full = extra >= h + w
        if path is None:
            if full:
                return math.inf, None
        elif full or (length - straight) / 2 + 2 <= extra:
            return length, path
        extra = min(h + w, max(2 * extra, int((length - straight) / 2) + 3
                               if path is not None else 2 * extra))


def _window_path(usable, a, b, extra):
    from skimage.graph import MCP_Geometric
    h, w = usable.shape
    r0, r1 = max(0, min(a[0], b[0]) - extra), min(h, max(a[0], b[0]) + extra + 1)
    c0, c1 = max(0, min(a[1], b[1]) - extra), min(w, max(a[1], b[1]) + extra + 1)
    win = usable[r0:r1, c0:c1]
    m = MCP_Geometric(np.where(win, 1.0, np.inf), fully_connected=True)
    sa, sb = (a[0] - r0, a[1] - c0), (b[0] - r0, b[1] - c0)
    cum, _ = m.find_costs([sa], [sb])
    if not np.isfinite(cum[sb]):
        return math.inf, None
    tb = [(r + r0, c + c0) for r, c in m.traceback(sb)]
    pulled = pull_string(usable, tb)
    return path_length(pulled), pulled
