"""The picture of the learning environment (``render_mode="rgb_array"``): the map and the
graph as the report draws them (:func:`patrolling_sim.model.draw.draw_graph`), vertices
coloured by their true idleness (green: just visited, red: idle for 2 T or more), the
robots as numbered discs (grey once failed)."""
import numpy as np

from patrolling_sim.common import paths
from patrolling_sim.model.draw import draw_graph, world_to_pixel
from spqrel_nav_lite.mapio import load_map

#: long side of the picture (px)
FRAME_SIZE = 600


def draw_frame(env) -> np.ndarray:
    """RGB uint8 (H, W, 3) picture of ``env`` (a PatrolParallelEnv after reset)."""
    import cv2
    cache = getattr(env, "render_cache", None)
    if cache is None or cache[0] != env.map_path:
        occ = load_map(paths.map_files(env.map_path)[0])
        env.render_cache = cache = (env.map_path, occ)
    occ = cache[1]
    scale = FRAME_SIZE / max(occ.width, occ.height)
    sim = env.sim
    idle = np.maximum(sim.t - np.asarray(sim.monitor.last_visit, dtype=float), 0.0)
    level = np.clip(idle / (2.0 * env.tab.T), 0.0, 1.0)
    colors = [(40, int(200 * (1 - x)), int(220 * x)) for x in level]
    img = draw_graph(occ, sim.g, scale=scale, vertex_colors=colors, labels=False)
    radius = max(4, int(round(0.6 / occ.resolution * scale)))
    for r in sim.robots:
        x, y = sim.true_position(r.id)
        c, row = world_to_pixel(occ, x, y)
        p = (int(round(c * scale)), int(round(row * scale)))
        failed = r.core is not None and r.core.failed
        color = (128, 128, 128) if failed else (200, 80, 20)
        cv2.circle(img, p, radius, color, -1, cv2.LINE_AA)
        cv2.putText(img, str(r.id), (p[0] - radius // 2, p[1] + radius // 2),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    return np.ascontiguousarray(img[:, :, ::-1])
