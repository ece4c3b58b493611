"""Obstacle-free navigation functions kept on disk, shared by processes and by runs.

The first search of a goal cell on a large map is a whole-map Dijkstra (about 120 ms of CPU
on broughton at 0.1 m); each ``nav_host`` or ``robot_nav`` process used to repeat it for
every patrol vertex, and every run repeated all of them (docs/navigation.md, "Plan store").
A :class:`PlanStore` keeps each result as one file, named by the goal cell, in a folder named
by a hash of the exact cell graph the search ran on (grid size, resolution, origin and every
edge weight), so a file is only ever read back for the graph it was computed on: another map,
another robot radius, inflation or resolution gives another folder. Files are read with
``numpy.load(mmap_mode="r")``: the processes of an experiment share the pages through the page
cache instead of each holding a private copy.

File format: a ``.npy`` array of shape (2, cells), int32; row 0 holds the float32 distances
(bit pattern), row 1 the predecessors (-9999 at the goal and at unreachable cells), exactly
what :meth:`~spqrel_nav_lite.planner_grid.PlannerGrid.free_navigation_function` computes.

Writes go to a temporary file renamed into place (atomic on POSIX), so concurrent writers of
the same goal are harmless and a reader never sees half a file. A file that cannot be read
or has the wrong shape counts as missing and is replaced. The store is bounded: when it holds
more than ``limit_bytes``, the least recently used files (by modification time, refreshed on
every first read by a process) are deleted down to 90 % of the bound; a process that has one
mapped keeps its pages (POSIX unlink semantics). A store that cannot be written (read-only,
full disk) logs one warning and is used read-only: navigation never fails because of it.
"""
import hashlib
import logging
import os
import threading
import time

import numpy as np

log = logging.getLogger(__name__)

#: bump when the file format or the meaning of a field changes: old folders are then ignored
FORMAT = b"spqrel_nav_lite navigation function v1"
#: temporary files older than this (s) are leftovers of a killed writer
STALE_TMP_S = 3600.0


def default_root():
    """``$PATROLLING_SIM_PLAN_STORE`` if set (empty or ``none``: no store), else
    ``$XDG_CACHE_HOME/patrolling_sim/plan_store`` (``~/.cache/...``)."""
    env = os.environ.get("PATROLLING_SIM_PLAN_STORE")
    if env is not None:
        return None if env.strip().lower() in ("", "none") else os.path.abspath(env)
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(cache, "patrolling_sim", "plan_store")


def graph_key(w, h, res, origin, graph):
    """Hex digest naming the cell graph: grid size, resolution, origin and the CSR arrays
    (every edge and weight) of the obstacle-free graph the searches run on."""
    d = hashlib.blake2b(FORMAT, digest_size=16)
    d.update(np.asarray([w, h], dtype=np.int64).tobytes())
    d.update(np.asarray([res, origin[0], origin[1]], dtype=np.float64).tobytes())
    for a in (graph.indptr, graph.indices, graph.data):
        d.update(np.ascontiguousarray(a).tobytes())
    return d.hexdigest()


class PlanStore:
    """The folder ``root/key`` of navigation functions over a grid of ``cells`` cells;
    ``limit_bytes`` bounds the whole of ``root`` (all keys)."""

    def __init__(self, root, key, cells, limit_bytes=4 << 30, description=""):
        self.root = os.path.abspath(root)
        self.dir = os.path.join(self.root, key)
        self.cells = int(cells)
        self.limit = max(0, int(limit_bytes))
        self.file_bytes = 128 + 8 * self.cells      # .npy header + two int32 rows
        self.writable = self.limit >= self.file_bytes
        self.loads = self.saves = 0
        self._lock = threading.Lock()
        self._used = None
        if self.writable:
            try:
                os.makedirs(self.dir, exist_ok=True)
                info = os.path.join(self.dir, "grid.txt")
                if description and not os.path.exists(info):
                    self._write_atomic(info, lambda f: f.write(description.encode()))
            except OSError as e:
                self._disable(e)

    def path(self, goal):
        return os.path.join(self.dir, f"{int(goal)}.npy")

    def load(self, goal):
        """(dist float32, pred int32) of ``goal`` as read-only arrays mapped from the file,
        or None when the store does not have it (or has a damaged copy, then removed)."""
        p = self.path(goal)
        try:
            a = np.load(p, mmap_mode="r", allow_pickle=False)
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as e:
            log.warning("plan store: %s is damaged (%s); searching again", p, e)
            self._remove(p)
            return None
        if a.dtype != np.int32 or a.shape != (2, self.cells):
            log.warning("plan store: %s has shape %s %s, expected (2, %d) int32; searching "
                        "again", p, a.shape, a.dtype, self.cells)
            self._remove(p)
            return None
        try:
            os.utime(p)          # least recently used goes first when the store is full
        except OSError:
            pass
        self.loads += 1
        a = np.asarray(a)
        return a[0].view(np.float32), a[1]

    def save(self, goal, dist, pred):
        """Store the field of ``goal`` (best effort: a failure disables further writes)."""
        if not self.writable:
            return
        a = np.empty((2, self.cells), dtype=np.int32)
        a[0] = np.asarray(dist, dtype=np.float32).view(np.int32)
        a[1] = pred
        try:
            self._write_atomic(self.path(goal), lambda f: np.save(f, a, allow_pickle=False))
        except OSError as e:
            self._disable(e)
            return
        self.saves += 1
        with self._lock:
            if self._used is None:
                self._used = self._scan()[0]
            else:
                self._used += self.file_bytes
            if self._used > self.limit:
                self._evict(keep=self.path(goal))

    # -- internals ---------------------------------------------------------------------------
    def _write_atomic(self, path, write):
        tmp = f"{path}.{os.getpid()}.{threading.get_ident()}.tmp"
        try:
            with open(tmp, "wb") as f:
                write(f)
            os.replace(tmp, path)
        except BaseException:
            self._remove(tmp)
            raise

    def _disable(self, err):
        if self.writable:
            log.warning("plan store: cannot write under %s (%s); using it read-only",
                        self.root, err)
        self.writable = False

    @staticmethod
    def _remove(path):
        try:
            os.unlink(path)
        except OSError:
            pass

    def _scan(self):
        """(bytes, [(mtime, size, path)]) of the store's files under ``root``; removes the
        temporary files of killed writers on the way."""
        total, files, now = 0, [], time.time()
        try:
            keys = list(os.scandir(self.root))
        except OSError:
            return 0, []
        for k in keys:
            if not k.is_dir(follow_symlinks=False):
                continue
            try:
                entries = list(os.scandir(k.path))
            except OSError:
                continue
            for e in entries:
                try:
                    st = e.stat(follow_symlinks=False)
                except OSError:
                    continue
                if e.name.endswith(".tmp"):
                    if now - st.st_mtime > STALE_TMP_S:
                        self._remove(e.path)
                    continue
                if e.name.endswith(".npy"):
                    total += st.st_size
                    files.append((st.st_mtime, st.st_size, e.path))
        return total, files

    def _evict(self, keep):
        total, files = self._scan()
        target = 0.9 * self.limit
        for _, size, path in sorted(files):
            if total <= target:
                break
            if path == keep:
                continue
            self._remove(path)
            total -= size
        self._used = total
