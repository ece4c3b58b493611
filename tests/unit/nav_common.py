"""Shared by the navigation unit tests (tests/unit/test_nav_core.py,
tests/unit/test_nav_scan_time.py): a laser scan of an occupancy map, ray-cast."""
import math

import numpy as np


def fake_scan(m, pose, angles, laser_x=0.15, rmax=20.0):
    """Exact-ish ray cast by small steps: the ranges from map pose ``pose`` (laser
    ``laser_x`` ahead of it) at bearings ``angles``, to the first cell that is not free."""
    sx, sy = pose[0] + laser_x * math.cos(pose[2]), pose[1] + laser_x * math.sin(pose[2])
    out = []
    for a in angles:
        t = 0.0
        while t < rmax:
            x, y = sx + t * math.cos(pose[2] + a), sy + t * math.sin(pose[2] + a)
            if m.cell_state(x, y) != "free":
                break
            t += m.resolution / 2
        out.append(t)
    return np.array(out)
