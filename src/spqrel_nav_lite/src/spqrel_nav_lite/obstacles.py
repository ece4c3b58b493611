"""Laser scans to points, and the short-term memory of obstacles the map does not explain."""
import math

import numpy as np


_BEAMS = {}     # (angle_min, angle_increment, beams, step) -> (angles, cos, sin)


def _beams(angle_min, angle_increment, n, step):
    """Bearings of every ``step``-th of ``n`` beams and their cosines and sines: the same
    for every scan of a laser, so computed once per laser geometry (the robots of a nav_host
    share their lasers' geometry). Read-only arrays; the dict is bounded."""
    key = (angle_min, angle_increment, n, step)
    beams = _BEAMS.get(key)
    if beams is None:
        a = angle_min + angle_increment * np.arange(0, n, step)
        beams = (a, np.cos(a), np.sin(a))
        for arr in beams:
            arr.setflags(write=False)
        if len(_BEAMS) > 64:
            _BEAMS.clear()
        _BEAMS[key] = beams
    return beams


def scan_points(ranges, angle_min, angle_increment, range_min, range_max, laser_x=0.0,
                step=1, max_range=None):
    """(N, 2) points in the robot frame from a scan (every ``step``-th beam, valid ranges only,
    optionally only those closer than ``max_range``). Also returns (ranges, angles) used."""
    r = np.asarray(ranges, dtype=float)[::step]
    a, ca, sa = _beams(angle_min, angle_increment, len(ranges), step)
    ok = np.isfinite(r) & (r >= max(range_min, 1e-3)) & (r < range_max)
    if max_range is not None:
        ok &= r <= max_range
    r = r[ok]
    pts = np.empty((len(r), 2))
    np.multiply(r, ca[:len(ok)][ok], out=pts[:, 0])
    pts[:, 0] += laser_x
    np.multiply(r, sa[:len(ok)][ok], out=pts[:, 1])
    return pts, r, a[:len(ok)][ok]


def to_world(points, pose):
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    out = np.empty_like(p)
    out[:, 0] = x + c * p[:, 0] - s * p[:, 1]
    out[:, 1] = y + s * p[:, 0] + c * p[:, 1]
    return out


def to_frame(points_world, pose):
    """The inverse of :func:`to_world`: world points seen from ``pose`` (its frame)."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    p = np.asarray(points_world, dtype=float).reshape(-1, 2)
    dx, dy = p[:, 0] - x, p[:, 1] - y
    out = np.empty_like(p)
    out[:, 0] = c * dx + s * dy
    out[:, 1] = -s * dx + c * dy
    return out


class ObstacleMemory:
    """Temporary obstacles: cells (size ``cell``) holding an unexplained laser point, each
    forgotten ``timeout`` seconds after it was last seen, or when a later beam passes through it
    (the cell lies well before that beam's end point)."""

    def __init__(self, cell=0.1, timeout=3.0):
        self.cell = float(cell)
        self.timeout = float(timeout)
        self._cells = {}        # (i, j) -> last seen time

    def __len__(self):
        return len(self._cells)

    def clear(self):
        self._cells.clear()

    def add(self, points_world, now):
        if len(points_world):
            ij = np.floor(np.asarray(points_world) / self.cell).astype(np.int64)
            for key in set(map(tuple, ij.tolist())):
                self._cells[key] = now

    def expire(self, now):
        dead = [k for k, t in self._cells.items() if now - t > self.timeout or t > now + 1.0]
        for k in dead:
            del self._cells[k]
        return bool(dead)

    def clear_seen_through(self, sensor_xy, hits_world, now, margin=0.3):
        """Forget cells that a beam from ``sensor_xy`` to one of ``hits_world`` crossed (the
        cell is nearer than the hit by more than ``margin`` and within 2 degrees of the beam)."""
        if not self._cells or not len(hits_world):
            return False
        keys = list(self._cells.keys())
        c = (np.array(keys, dtype=float) + 0.5) * self.cell
        sx, sy = sensor_xy
        dc = np.hypot(c[:, 0] - sx, c[:, 1] - sy)
        ac = np.arctan2(c[:, 1] - sy, c[:, 0] - sx)
        h = np.asarray(hits_world, dtype=float)
        dh = np.hypot(h[:, 0] - sx, h[:, 1] - sy)
        ah = np.arctan2(h[:, 1] - sy, h[:, 0] - sx)
        # nearest beam by bearing: binary search in the sorted bearings, the neighbours on
        # both sides (with wrap-around at +-pi) -- O((cells + hits) log hits)
        order = np.argsort(ah)
        ah, dh = ah[order], dh[order]
        m = len(ah)
        k = np.searchsorted(ah, ac)
        k0, k1 = (k - 1) % m, k % m
        d0 = np.abs((ac - ah[k0] + np.pi) % (2 * np.pi) - np.pi)
        d1 = np.abs((ac - ah[k1] + np.pi) % (2 * np.pi) - np.pi)
        near = np.where(d1 < d0, k1, k0)
        diff = np.minimum(d0, d1)
        seen = np.fromiter((self._cells[q] for q in keys), dtype=float, count=len(keys))
        crossed = (diff < math.radians(2.0)) & (dc < dh[near] - margin) & (now - seen > 0.0)
        for q, cr in zip(keys, crossed):
            if cr:
                del self._cells[q]
        return bool(crossed.any())

    def points(self):
        if not self._cells:
            return np.zeros((0, 2))
        return (np.array(list(self._cells.keys()), dtype=float) + 0.5) * self.cell
