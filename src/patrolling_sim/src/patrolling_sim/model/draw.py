"""Drawing helpers (OpenCV): the patrol graph over its map, for people.

Used to produce the ``<map>-graph.png`` pictures, and by viewers and reports.
"""
import numpy as np


def world_to_pixel(occupancy, x, y):
    """Image pixel (column, row from top) of a map-frame point, as floats."""
    c = (x - occupancy.origin[0]) / occupancy.resolution
    r = occupancy.height - (y - occupancy.origin[1]) / occupancy.resolution
    return c, r


def draw_graph(occupancy, pgraph, scale=None, vertex_colors=None, labels=True):
    """Return a BGR uint8 image of the map with the graph drawn on it.

    Args:
        occupancy: :class:`spqrel_nav_lite.mapio.OccupancyMap`.
        pgraph: :class:`patrolling_sim.model.graph.PatrolGraph`.
        scale: output scale factor (default: so that the long side is ~1200 px, at least 1).
        vertex_colors: optional list of BGR tuples, one per vertex.
        labels: draw vertex ids.
    """
    import cv2
    if scale is None:
        scale = max(1.0, 1200.0 / max(occupancy.width, occupancy.height))
    img = cv2.cvtColor(occupancy.to_image(), cv2.COLOR_GRAY2BGR)
    if scale != 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    pts = []
    for x, y in pgraph.pos:
        c, r = world_to_pixel(occupancy, x, y)
        pts.append((int(round(c * scale)), int(round(r * scale))))
    thick = max(1, int(round(scale)))
    for u in range(pgraph.n):
        for w, _ in pgraph.neighbors[u]:
            if u < w:
                cv2.line(img, pts[u], pts[w], (60, 160, 60), thick, cv2.LINE_AA)
    radius = max(4, int(round(3 * scale)))
    font = max(0.4, 0.35 * scale)
    for v, p in enumerate(pts):
        color = vertex_colors[v] if vertex_colors is not None else (40, 40, 220)
        cv2.circle(img, p, radius, color, -1, cv2.LINE_AA)
        if labels:
            cv2.putText(img, str(v), (p[0] + radius, p[1] - radius), cv2.FONT_HERSHEY_SIMPLEX,
                        font, (200, 30, 30), max(1, thick // 2), cv2.LINE_AA)
    return img


def save_png(img, path):
    import cv2
    if not cv2.imwrite(path, np.ascontiguousarray(img)):
        raise OSError(f"{path}: cannot write PNG")
