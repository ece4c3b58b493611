"""Occupancy maps in map_server format: a yaml file plus an image (pgm/png).

:func:`load_map` follows map_server's "trinary" interpretation:

- each pixel's value is the mean of its colour channels, ``p = (255 - v) / 255``
  (``p = v / 255`` with ``negate: 1``);
- ``p > occupied_thresh`` -> 100 (occupied), ``p < free_thresh`` -> 0 (free), else -1.

The returned :class:`OccupancyMap` stores the grid in ``nav_msgs/OccupancyGrid`` order:
row 0 is the *bottom* row of the image (the map origin), so ``data[j, i]`` is the cell whose
lower-left corner is ``origin + (i, j) * resolution``.
"""
import math
import os

import numpy as np
import yaml

from .errors import MapFormatError

FREE, OCCUPIED, UNKNOWN = 0, 100, -1


class OccupancyMap:
    """An occupancy grid with its metadata (see module docstring).

    Attributes:
        data: (height, width) int8 array of 0 / 100 / -1, row 0 = bottom.
        resolution: metres per cell.
        origin: (x, y, yaw) of the lower-left corner of cell (0, 0) in the map frame.
        width, height: size in cells.
        yaml_path, image_path: source files (may be None for synthetic maps).
        negate, occupied_thresh, free_thresh: as in the yaml.
    """

    def __init__(self, data, resolution, origin=(0.0, 0.0, 0.0), yaml_path=None,
                 image_path=None, negate=0, occupied_thresh=0.65, free_thresh=0.196):
        self.data = np.asarray(data, dtype=np.int8)
        self.resolution = float(resolution)
        self.origin = tuple(float(v) for v in origin)
        self.height, self.width = self.data.shape
        self.yaml_path = yaml_path
        self.image_path = image_path
        self.negate = negate
        self.occupied_thresh = occupied_thresh
        self.free_thresh = free_thresh
        self._clearance = None

    @property
    def size_m(self):
        return self.width * self.resolution, self.height * self.resolution

    def world_to_cell(self, x, y):
        """(i, j) = (column, row from bottom) of the cell containing (x, y) metres."""
        i = int(math.floor((x - self.origin[0]) / self.resolution))
        j = int(math.floor((y - self.origin[1]) / self.resolution))
        return i, j

    def cell_to_world(self, i, j):
        """Centre of cell (i, j) in metres."""
        return (self.origin[0] + (i + 0.5) * self.resolution,
                self.origin[1] + (j + 0.5) * self.resolution)

    def in_bounds(self, x, y):
        i, j = self.world_to_cell(x, y)
        return 0 <= i < self.width and 0 <= j < self.height

    def cell_state(self, x, y):
        """'free', 'occupied', 'unknown' or 'out-of-map' for the cell at (x, y)."""
        i, j = self.world_to_cell(x, y)
        if not (0 <= i < self.width and 0 <= j < self.height):
            return "out-of-map"
        v = self.data[j, i]
        return "free" if v == FREE else ("occupied" if v == OCCUPIED else "unknown")

    def is_free(self, x, y):
        return self.cell_state(x, y) == "free"

    @property
    def clearance(self):
        """(height, width) float32 array: distance in metres from each cell centre to the
        edge of the nearest non-free cell (occupied, unknown or beyond the map border),
        i.e. centre-to-centre distance minus half a cell. Computed once."""
        if self._clearance is None:
            import cv2
            free = (self.data == FREE).astype(np.uint8)
            # pad so the map border counts as an obstacle
            padded = np.pad(free, 1, constant_values=0)
            d = cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
            self._clearance = (np.maximum(d[1:-1, 1:-1] - 0.5, 0.0)
                               * self.resolution).astype(np.float32)
        return self._clearance

    def clearance_at(self, x, y):
        """Clearance (m) at (x, y); 0 outside the map. The value of :attr:`clearance`; while
        that grid is not computed, found for this one cell (:meth:`_cell_clearance`)."""
        i, j = self.world_to_cell(x, y)
        if not (0 <= i < self.width and 0 <= j < self.height):
            return 0.0
        if self._clearance is not None:
            return float(self._clearance[j, i])
        return self._cell_clearance(i, j)

    def _cell_clearance(self, i, j):
        """``clearance[j, i]`` computed for one cell: the exact Euclidean distance (in cells)
        to the nearest non-free cell centre, the padding border included, found in square
        windows around the cell that double in size, then the grid's formula.

        Why not the grid: checking a few start positions (every graph-mode run and campaign
        worker does it) needed OpenCV's import (0.2-0.5 s) and a transform of the whole map.
        OpenCV's precise transform is float32(sqrt(squared integer distance)); the tests
        compare this with the grid on every shipped map."""
        data = self.data
        h, w = data.shape
        if data[j, i] != FREE:
            d2 = 0
        else:
            d2 = min(i + 1, w - i, j + 1, h - j) ** 2      # the padding border's cells
            r = 1
            while True:
                j0, i0 = max(0, j - r), max(0, i - r)
                rows, cols = np.nonzero(data[j0:j + r + 1, i0:i + r + 1] != FREE)
                if len(rows):
                    d2 = min(d2, int(((rows + (j0 - j)) ** 2 + (cols + (i0 - i)) ** 2).min()))
                if d2 <= r * r:                # every cell outside the window is farther
                    break
                r *= 2
        d = np.sqrt(np.array([d2], dtype=np.float64)).astype(np.float32)
        return float((np.maximum(d - 0.5, 0.0) * self.resolution).astype(np.float32)[0])

    def to_image(self):
        """(height, width) uint8 grey image, top row first (free 254, occupied 0,
        unknown 205), as map_saver writes it."""
        img = np.full(self.data.shape, 205, dtype=np.uint8)
        img[self.data == FREE] = 254
        img[self.data == OCCUPIED] = 0
        return img[::-1].copy()


_REQUIRED = ("image", "resolution", "origin")


def load_map(yaml_path):
    """Load a map_server yaml and its image.

    Raises:
        MapFormatError: one line naming the yaml (and key) or the image and the problem.
    """
    try:
        with open(yaml_path, encoding="utf-8") as f:
            meta = yaml.safe_load(f)
    except FileNotFoundError:
        raise MapFormatError(f"{yaml_path}: map yaml not found") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f":{mark.line + 1}" if mark else ""
        raise MapFormatError(f"{yaml_path}{where}: invalid YAML "
                             f"({getattr(e, 'problem', None) or e.__class__.__name__})") from None
    except (OSError, UnicodeDecodeError) as e:
        raise MapFormatError(
            f"{yaml_path}: cannot read map yaml ({e.__class__.__name__})") from None
    if not isinstance(meta, dict):
        raise MapFormatError(f"{yaml_path}: map yaml must be a mapping with keys "
                             f"{', '.join(_REQUIRED)}")
    for k in _REQUIRED:
        if k not in meta:
            raise MapFormatError(f"{yaml_path}: missing key '{k}'")

    def number(key, default=None, lo=None, hi=None):
        v = meta.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise MapFormatError(f"{yaml_path}: key '{key}' must be a number, got {v!r}")
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise MapFormatError(f"{yaml_path}: key '{key}' = {v} is outside [{lo}, {hi}]")
        return float(v)

    res = number("resolution")
    if res <= 0:
        raise MapFormatError(f"{yaml_path}: key 'resolution' must be positive, got {res}")
    origin = meta["origin"]
    if (not isinstance(origin, (list, tuple)) or len(origin) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in origin)):
        raise MapFormatError(f"{yaml_path}: key 'origin' must be [x, y, yaw], got {origin!r}")
    occ = number("occupied_thresh", 0.65, 0.0, 1.0)
    free = number("free_thresh", 0.196, 0.0, 1.0)
    if free > occ:
        raise MapFormatError(f"{yaml_path}: free_thresh {free} is above occupied_thresh {occ}")
    negate = meta.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise MapFormatError(f"{yaml_path}: key 'negate' must be 0 or 1, got {negate!r}")
    image = meta["image"]
    if not isinstance(image, str) or not image:
        raise MapFormatError(f"{yaml_path}: key 'image' must be a file name, got {image!r}")
    image_path = image if os.path.isabs(image) else os.path.join(
        os.path.dirname(os.path.abspath(yaml_path)), image)
    data = image_to_occupancy(read_image(image_path, yaml_path), bool(negate), occ, free)
    return OccupancyMap(data, res, tuple(origin), yaml_path=yaml_path, image_path=image_path,
                        negate=int(bool(negate)), occupied_thresh=occ, free_thresh=free)


_PNM_SPACE = b" \t\r\n\x0b\x0c"


def read_pgm8(image_path):
    """The pixels of a binary 8-bit PGM (``P5``, maxval 255: what map_saver writes and what
    every shipped map is) as a read-only (height, width) uint8 array, top row first; None for
    any other file, which :func:`read_image` leaves to OpenCV.

    Why not OpenCV here too: importing ``cv2`` is slow, and every graph-mode run and every
    campaign worker would pay for it only to read this trivial format (bench/notes/campaign.md,
    "The campaign's start-up"). The result equals ``cv2.imread(path,
    cv2.IMREAD_UNCHANGED)`` (tests/unit/test_mapio.py compares them on every shipped map and
    on headers with comments)."""
    try:
        with open(image_path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    if data[:2] != b"P5":
        return None
    fields, i, n = [], 2, len(data)
    while len(fields) < 3:                     # width, height, maxval
        while i < n and (data[i] in _PNM_SPACE or data[i] == 0x23):
            if data[i] == 0x23:                # '#': a comment to the end of the line
                while i < n and data[i] not in b"\r\n":
                    i += 1
            else:
                i += 1
        j = i
        while j < n and 0x30 <= data[j] <= 0x39:
            j += 1
        if j == i:
            return None
        fields.append(int(data[i:j]))
        i = j
    if i >= n or data[i] not in _PNM_SPACE:    # one whitespace byte, then the raster
        return None
    i += 1
    w, h, maxval = fields
    if maxval != 255 or w <= 0 or h <= 0 or n - i < w * h:
        return None
    return np.frombuffer(data, np.uint8, w * h, i).reshape(h, w)


def read_image(image_path, yaml_path="map yaml"):
    """Read a map image as a float array of mean channel values (0..255), top row first.
    8-bit binary PGM through :func:`read_pgm8`, every other format through OpenCV."""
    if not os.path.isfile(image_path):
        raise MapFormatError(f"{yaml_path}: image '{image_path}' not found")
    img = read_pgm8(image_path)
    if img is None:
        import cv2
        img = cv2.imread(image_path, cv2.IMREAD_UNCHANGED)
    if img is None or img.size == 0:
        raise MapFormatError(f"{image_path}: cannot decode map image")
    img = img.astype(np.float64)
    if img.ndim == 3:
        channels = img.shape[2]
        if channels == 4:   # ignore alpha as map_server does in trinary mode
            img = img[:, :, :3]
        img = img.mean(axis=2)
    if img.max() > 255:     # 16-bit images
        img = img / 257.0
    return img


def image_to_occupancy(img, negate, occupied_thresh, free_thresh):
    """Convert an image (0..255, top row first) to an int8 grid, bottom row first."""
    p = img / 255.0 if negate else (255.0 - img) / 255.0
    data = np.full(img.shape, UNKNOWN, dtype=np.int8)
    data[p > occupied_thresh] = OCCUPIED
    data[p < free_thresh] = FREE
    return data[::-1].copy()
