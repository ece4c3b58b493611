"""Monte-Carlo localisation (an AMCL equivalent), vectorised with numpy.

- motion: differential-drive odometry model (rot1, trans, rot2) with noise ``alpha1..4``
  (amcl's "diff" model, whose standard deviations are ``alpha1*rot^2 + alpha2*trans^2`` etc.,
  or "diff-corrected", where those expressions are variances);
- sensor: likelihood field over a distance map (distance to the nearest occupied cell, capped
  at ``max_dist``), beams combined like amcl (``p = 1 + sum pz^3``);
- resampling: low-variance (systematic), KLD-adaptive particle count between ``min_particles``
  and ``max_particles`` (bins 0.5 m x 0.5 m x 10 deg, ``kld_err``, ``kld_z``).
"""
import math

import numpy as np

from .mapio import FREE, OCCUPIED

from .geometry import normalize_angle


def first_in_bins(particles):
    """Indices (ascending) of the first particle in each occupied KLD bin (0.5 m x 0.5 m x
    10 degrees). Each bin gets one int64 key (offsets from the smallest occupied bin, so the
    key is unique per bin), and a 1-D ``np.unique`` finds the first of each: the same indices
    as ``np.unique(bins, axis=0, return_index=True)``, 4-8x faster (0.56 -> 0.12 ms for 500
    particles), since unique rows are found by sorting a structured view."""
    bins = np.column_stack([np.floor(particles[:, 0] / 0.5), np.floor(particles[:, 1] / 0.5),
                            np.floor(particles[:, 2] / math.radians(10.0))]).astype(np.int64)
    lo = bins.min(axis=0)
    span = bins.max(axis=0) - lo + 1
    b = bins - lo
    key = (b[:, 0] * span[1] + b[:, 1]) * span[2] + b[:, 2]
    _, first = np.unique(key, return_index=True)   # stable sort: first occurrences
    return np.sort(first)


class LikelihoodField:
    """Distance (m) from each cell to the nearest occupied cell, capped at ``max_dist``."""

    def __init__(self, omap, max_dist=2.0):
        import cv2
        self.map = omap
        self.res = omap.resolution
        self.ox, self.oy = omap.origin[0], omap.origin[1]
        self.max_dist = float(max_dist)
        notocc = (omap.data != OCCUPIED).astype(np.uint8)
        d = cv2.distanceTransform(notocc, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * self.res
        self.dist = np.minimum(d, self.max_dist).astype(np.float32)
        self.h, self.w = self.dist.shape
        fj, fi = np.nonzero(omap.data == FREE)
        self.free_cells = np.column_stack([fi, fj])

    def lookup(self, x, y):
        """Distances at arrays of points; ``max_dist`` outside the map."""
        i = np.floor((x - self.ox) / self.res).astype(np.int64)
        j = np.floor((y - self.oy) / self.res).astype(np.int64)
        inside = (i >= 0) & (i < self.w) & (j >= 0) & (j < self.h)
        out = np.full(np.shape(x), self.max_dist, dtype=np.float64)
        out[inside] = self.dist[j[inside], i[inside]]
        return out

    def is_free(self, x, y):
        i = np.floor((x - self.ox) / self.res).astype(np.int64)
        j = np.floor((y - self.oy) / self.res).astype(np.int64)
        inside = (i >= 0) & (i < self.w) & (j >= 0) & (j < self.h)
        ok = np.zeros(np.shape(x), dtype=bool)
        ok[inside] = self.map.data[j[inside], i[inside]] == FREE
        return ok


class ParticleFilter:
    def __init__(self, field, min_particles=100, max_particles=500, alphas=(0.2, 0.2, 0.8, 0.2),
                 z_hit=0.5, z_rand=0.5, sigma_hit=0.2, laser_max_range=20.0, kld_err=0.05,
                 kld_z=0.99, laser_x=0.15, rng=None, model="diff"):
        if not 0 < min_particles <= max_particles:
            raise ValueError(f"need 0 < min_particles <= max_particles, got "
                             f"{min_particles}, {max_particles}")
        self.field = field
        self.min_particles = int(min_particles)
        self.max_particles = int(max_particles)
        self.alphas = tuple(float(a) for a in alphas)
        self.z_hit, self.z_rand, self.sigma_hit = float(z_hit), float(z_rand), float(sigma_hit)
        self.laser_max_range = float(laser_max_range)
        self.kld_err, self.kld_z = float(kld_err), float(kld_z)
        self.laser_x = float(laser_x)
        if model not in ("diff", "diff-corrected"):
            raise ValueError(f"odom model must be 'diff' or 'diff-corrected', got {model!r}")
        self.model = model
        self.rng = rng if rng is not None else np.random.default_rng()
        self.particles = np.zeros((self.max_particles, 3))
        self.weights = np.full(self.max_particles, 1.0 / self.max_particles)

    # -- initialisation ------------------------------------------------------------------------
    def init_gaussian(self, mean, cov_xx=0.25, cov_yy=0.25, cov_aa=(math.pi / 12) ** 2):
        n = self.max_particles
        p = np.empty((n, 3))
        p[:, 0] = self.rng.normal(mean[0], math.sqrt(max(cov_xx, 0.0)), n)
        p[:, 1] = self.rng.normal(mean[1], math.sqrt(max(cov_yy, 0.0)), n)
        p[:, 2] = normalize_angle(self.rng.normal(mean[2], math.sqrt(max(cov_aa, 0.0)), n))
        self.particles = p
        self.weights = np.full(n, 1.0 / n)

    def init_uniform(self):
        """Particles spread uniformly over the free cells (global localisation)."""
        cells = self.field.free_cells
        if not len(cells):
            raise ValueError("the map has no free cell")
        n = self.max_particles
        k = self.rng.integers(0, len(cells), n)
        res = self.field.res
        p = np.empty((n, 3))
        p[:, 0] = self.field.ox + (cells[k, 0] + self.rng.random(n)) * res
        p[:, 1] = self.field.oy + (cells[k, 1] + self.rng.random(n)) * res
        p[:, 2] = self.rng.uniform(-math.pi, math.pi, n)
        self.particles = p
        self.weights = np.full(n, 1.0 / n)

    # -- motion ----------------------------------------------------------------------------------
    def predict(self, odom_old, odom_new):
        """Move the particles by the odometry increment between two odom poses."""
        dx, dy = odom_new[0] - odom_old[0], odom_new[1] - odom_old[1]
        trans = math.hypot(dx, dy)
        rot1 = 0.0 if trans < 0.01 else normalize_angle(math.atan2(dy, dx) - odom_old[2])
        rot2 = normalize_angle(odom_new[2] - odom_old[2] - rot1)
        # driving backwards: measure rot1 against the reversed heading (as amcl does)
        r1n = min(abs(rot1), abs(normalize_angle(rot1 - math.pi)))
        r2n = min(abs(rot2), abs(normalize_angle(rot2 - math.pi)))
        a1, a2, a3, a4 = self.alphas
        n = len(self.particles)
        sd_r1 = a1 * r1n * r1n + a2 * trans * trans
        sd_t = a3 * trans * trans + a4 * r1n * r1n + a4 * r2n * r2n
        sd_r2 = a1 * r2n * r2n + a2 * trans * trans
        if self.model == "diff-corrected":     # alphas scale variances
            sd_r1, sd_t, sd_r2 = math.sqrt(sd_r1), math.sqrt(sd_t), math.sqrt(sd_r2)
        # "diff" (amcl's original model, the one the original launch files use): the same
        # expressions are used directly as standard deviations
        r1 = rot1 - self.rng.normal(0.0, 1.0, n) * sd_r1
        t = trans - self.rng.normal(0.0, 1.0, n) * sd_t
        r2 = rot2 - self.rng.normal(0.0, 1.0, n) * sd_r2
        p = self.particles
        h = p[:, 2] + r1
        p[:, 0] += t * np.cos(h)
        p[:, 1] += t * np.sin(h)
        p[:, 2] = normalize_angle(h + r2)

    # -- sensor ------------------------------------------------------------------------------------
    def update(self, ranges, angles):
        """Weight the particles with the beams (ranges, angles in the laser frame); beams at or
        beyond the max range are ignored. Returns the total (un-normalised) weight."""
        r = np.asarray(ranges, dtype=float)
        a = np.asarray(angles, dtype=float)
        ok = np.isfinite(r) & (r < self.laser_max_range) & (r > 0.0)
        r, a = r[ok], a[ok]
        if not len(r):
            return 0.0
        p = self.particles
        c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
        lx = p[:, 0] + self.laser_x * c
        ly = p[:, 1] + self.laser_x * s
        ang = p[:, 2:3] + a[None, :]
        hx = lx[:, None] + r[None, :] * np.cos(ang)
        hy = ly[:, None] + r[None, :] * np.sin(ang)
        z = self.field.lookup(hx, hy)
        pz = self.z_hit * np.exp(-(z * z) / (2.0 * self.sigma_hit ** 2)) \
            + self.z_rand / self.laser_max_range
        w = 1.0 + np.sum(pz * pz * pz, axis=1)
        w = self.weights * w
        total = float(w.sum())
        if total > 0 and np.isfinite(total):
            self.weights = w / total
        else:
            self.weights = np.full(len(p), 1.0 / len(p))
        return total

    # -- resampling ------------------------------------------------------------------------------
    def kld_limit(self, k):
        """Particles needed for k occupied histogram bins (Fox's KLD bound)."""
        return int(self._kld_limits(np.array([k]))[0])

    def _kld_limits(self, k):
        """Vectorised KLD bound; like amcl, ``kld_z`` is used as the normal quantile."""
        k = np.asarray(k, dtype=float)
        km1 = np.maximum(k - 1.0, 1.0)
        a = 2.0 / (9.0 * km1)
        n = km1 / (2.0 * self.kld_err) * (1.0 - a + np.sqrt(a) * self.kld_z) ** 3
        n = np.where(k <= 1, self.min_particles, np.ceil(n))
        return np.clip(n, self.min_particles, self.max_particles).astype(int)

    def resample(self):
        """Low-variance resampling to a KLD-adaptive number of particles."""
        p, w = self.particles, self.weights
        m = self.max_particles
        cum = np.cumsum(w)
        cum[-1] = 1.0
        u = (self.rng.random() + np.arange(m)) / m
        idx = np.searchsorted(cum, u)
        cand = p[idx][self.rng.permutation(m)]
        # KLD: number of particles needed given the bins occupied by the first n samples
        first = first_in_bins(cand)
        ns = np.arange(self.min_particles, m + 1)
        enough = ns >= self._kld_limits(np.searchsorted(first, ns))
        n_needed = int(ns[np.argmax(enough)]) if enough.any() else m
        self.particles = cand[:n_needed].copy()
        self.weights = np.full(n_needed, 1.0 / n_needed)

    # -- estimate ----------------------------------------------------------------------------------
    def estimate(self):
        """(x, y, yaw) mean of the particles near the best one, and the (3, 3) covariance."""
        p, w = self.particles, self.weights
        best = p[int(np.argmax(w))]
        near = (np.hypot(p[:, 0] - best[0], p[:, 1] - best[1]) < 1.0) & \
            (np.abs(normalize_angle(p[:, 2] - best[2])) < 0.6)
        q, ww = p[near], w[near]
        ww = ww / ww.sum()
        mx, my = float(np.dot(ww, q[:, 0])), float(np.dot(ww, q[:, 1]))
        ma = math.atan2(float(np.dot(ww, np.sin(q[:, 2]))), float(np.dot(ww, np.cos(q[:, 2]))))
        d = np.column_stack([q[:, 0] - mx, q[:, 1] - my, normalize_angle(q[:, 2] - ma)])
        cov = (d * ww[:, None]).T @ d
        return (mx, my, ma), cov
