"""Shared pieces of the DTA family (Farinelli, Iocchi, Nardi, "Distributed on-line dynamic
task assignment for multi-robot patrolling", Autonomous Robots 41(6), 2017): a global
idleness *estimate* that ages with time and is merged from teammates' type-40 messages."""
import heapq
import logging

import numpy as np

from patrolling_sim.common import paths
from patrolling_sim.model.dta_params import load_dta_params
from patrolling_sim.common.protocol import INT16_CAP, INT16_MAX, MSG_DTA_IDLENESS

#: the payload carries idleness in tenths of a second
IDLENESS_SCALE = 10.0
log = logging.getLogger(__name__)


class IdlenessEstimate:
    """``gi[v]``: estimated idleness (s) of every vertex (a numpy array), advanced lazily to
    the clock."""

    def __init__(self, n, initial, now):
        self.values = np.full(n, float(initial))
        self.t = now
        self.clamped = 0                # payload entries clamped so far (logged once)

    def advance(self, now):
        dt = now - self.t
        if dt > 0:
            self.values += dt
            self.t = now
        return self.values

    def merge(self, received, now):
        """Take the smaller of own and received (message payload is 10 x seconds)."""
        g = self.advance(now)
        r = np.asarray(received[:len(g)], dtype=float) / IDLENESS_SCALE
        np.minimum(g[:len(r)], r, out=g[:len(r)])

    def merge_seconds(self, received, now):
        """:meth:`merge` of a payload already decoded to seconds by :func:`decode_seconds`
        (an array of the estimate's length): the same element-wise minimum, without the
        conversion (the same numbers: the conversion is the same division, done once)."""
        g = self.advance(now)
        np.minimum(g, received, out=g)

    def encode(self, now, zero=None):
        """Payload ``I_0..I_{V-1}``: int(10 * gi), values above INT16_MAX replaced by
        INT16_CAP (the original replaces values above 32768, so 32768 itself wraps to
        -32768 in its int16 message; here every value that does not fit is capped)."""
        x = (IDLENESS_SCALE * self.advance(now)).astype(np.int64)
        if zero is not None:
            x[zero] = 0
        over = x > INT16_MAX
        if over.any():
            if not self.clamped:
                k = int(np.argmax(over))
                log.warning("idleness estimate %.0f s of vertex %d exceeds the int16 payload; "
                            "sent as %d (the original's clamp)", self.values[k], k, INT16_CAP)
            self.clamped += int(over.sum())
            x[over] = INT16_CAP
        return x.tolist()


def _counting(name):
    """dict method ``name`` that also counts a change (VersionedDict)."""
    def method(self, *a, **kw):
        self.version += 1
        return getattr(dict, name)(self, *a, **kw)
    method.__name__ = name
    return method


class VersionedDict(dict):
    """A dict that counts its changes (``version``), so a value derived from it can be
    recomputed only when it changed (DTAP's task set is derived from the bid table after
    every received bid; most bids change nothing)."""
    __slots__ = ("version",)

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.version = 0

    def __setitem__(self, k, v):
        self.version += 1
        super().__setitem__(k, v)

    def __delitem__(self, k):
        self.version += 1
        super().__delitem__(k)

    pop, popitem, clear, update, setdefault, __ior__ = (
        _counting(m) for m in ("pop", "popitem", "clear", "update", "setdefault", "__ior__"))


def dta_params(ctx, file_name, defaults):
    """DTA parameters: ``ctx.params['dta_params']`` file if given, else the shipped
    ``params/DTA/<file_name>.params``; keys missing from the file read as 0 (the original's
    rule), keys missing from both the file and ``defaults``' keys are ignored."""
    path = ctx.params.get("dta_params") or paths.dta_params_file(file_name)
    got = load_dta_params(path)
    return {k: float(got.get(k, 0.0)) for k in defaults}


def decode_idleness(data, n):
    """(values as a float array of 10 x seconds, next) from ``[id, 40, I_0..I_{n-1}, next]``,
    or None if malformed."""
    if len(data) != n + 3 or data[1] != MSG_DTA_IDLENESS:
        return None
    return np.asarray(data[2:2 + n], dtype=float), data[2 + n]


#: most decoded payloads kept per graph (see :func:`decode_seconds`); emptied when full
DECODED_MAX = 512


def decode_seconds(data, pgraph):
    """(idleness in seconds as a read-only float array, next) from
    ``[id, 40, I_0..I_{n-1}, next]`` for the graph ``pgraph``, or None if malformed:
    :func:`decode_idleness` divided by :data:`IDLENESS_SCALE`.

    A message reaches every teammate with the same content, so each is converted once
    instead of once per receiver (the conversion was half of a large team's run time): the
    results are kept in ``pgraph.derived["dta_decoded"]``, keyed by the message's content,
    so sharing them between the robots of one simulation (or the runs of one map in a
    campaign worker) cannot change a result. The last message decoded is also kept by
    identity: graph mode hands every receiver the same tuple, found again without hashing
    its V + 3 entries (the memo holds the tuple, so its id cannot be reused)."""
    derived = pgraph.derived
    last = derived.get("dta_last")
    if last is not None and last[0] is data:
        return last[1]
    n = pgraph.n
    if len(data) != n + 3 or data[1] != MSG_DTA_IDLENESS:
        return None
    key = data if type(data) is tuple else tuple(data)
    cache = derived.get("dta_decoded")
    if cache is None:
        cache = derived["dta_decoded"] = {}
    hit = cache.get(key)
    if hit is None:
        sec = np.array(data[2:2 + n], dtype=float) / IDLENESS_SCALE
        sec.flags.writeable = False
        if len(cache) >= DECODED_MAX:
            cache.clear()
        hit = cache[key] = (sec, data[2 + n])
    derived["dta_last"] = (key, hit)
    return hit


def path_hops(pgraph):
    """(n, n) array: the number of edges on the cost-shortest path the original's Dijkstra
    returns (the DTA agents count hops on it, not on a fewest-edge path). Ties between
    equally cheap paths resolve as there: vertices are settled in (distance, id) order and a
    path is replaced only by a strictly cheaper one, neighbours scanned in file order.
    Unreachable pairs are inf. Computed once per graph object."""
    cache = pgraph.derived.setdefault("dta_path_hops", {})
    if "hops" not in cache:
        n = pgraph.n
        hops = np.full((n, n), np.inf)
        for s in range(n):
            dist = {s: 0.0}
            h = {s: 0}
            heap = [(0.0, s)]
            done = set()
            while heap:
                d, u = heapq.heappop(heap)
                if u in done:
                    continue
                done.add(u)
                for w, c in pgraph.neighbors[u]:
                    if w in done:
                        continue
                    nd = d + c
                    if nd < dist.get(w, float("inf")):
                        dist[w] = nd
                        h[w] = h[u] + 1
                        heapq.heappush(heap, (nd, w))
            for v, k in h.items():
                hops[s, v] = k
        cache["hops"] = hops
    return cache["hops"]
