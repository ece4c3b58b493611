"""DTAP, DTA with sequential single-item auctions and partition-based bids (``DTASSIPart``;
Farinelli, Iocchi, Nardi, Autonomous Robots 41(6), 2017).

Every robot keeps a global idleness estimate ``gi`` (2V s at start, ageing, merged with the
teammates' type-40 messages by taking the minimum) and a set of *tasks*: vertices for which it
holds the best (lowest) bid. It looks one step ahead: on reaching a vertex it heads to the
target it already won and meanwhile auctions the one after it, starting from that target cv:

1. take the not-yet-excluded vertex v maximising
   ``U(cv, v) = theta_idleness * gi[v] + theta_hop * hops(cv, v) * V``;
2. bid on it and broadcast ``[id, 41, v, bid]``; teammates record the bid, compute theirs
   and reply ``[id, 42, v, bid]`` when theirs is better;
3. after ``min(timeout, 1 + 0.1 * |tasks|)`` s (a timer: the robot keeps driving) v is won
   if the best bid is ours, or taken anyway if it is adjacent to cv and its idleness is an
   outlier (> mean + 2 SD) with a non-zero best bid; otherwise the next-best vertex is
   auctioned (exclusions reset when exhausted).

Bid (partition-based): ``pathcost(v, center) * (1 + |tasks|)``, center = the task vertex with
the smallest summed path cost to all tasks; 0 if v already is our next target. A stored best
bid is replaced when ``stored >= (1 + hist) * new``. Parameters from
``params/DTA/DTASSI.params`` (timeout 3, theta_idleness 1, theta_navigation 0,
theta_hop -2, threshold 0, hist 0). After each arrival the robot broadcasts
``[id, 40, I_0..I_{V-1}, next]``. If it arrives before an auction is decided, it takes the
best candidate by U.
"""
import numpy as np

from .base import (INT16_CAP, INT16_MAX, MSG_DTA_IDLENESS, MSG_SSI_BID,
                   MSG_SSI_TASK_REQUEST, PatrolStrategy, register)
from .dta_common import IdlenessEstimate, decode_idleness, dta_params

DEFAULTS = {"timeout": 3.0, "theta_idleness": 1.0, "theta_navigation": 0.0,
            "theta_hop": -2.0, "threshold": 0.0, "hist": 0.0}


@register
class DTASSIPart(PatrolStrategy):
    name = "DTAP"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.p = dta_params(ctx, "DTASSI", DEFAULTS)
        self.algorithm_params = ",".join(f"{self.p[k]:g}" for k in DEFAULTS)
        self.gi = None
        self.best_bid = {}          # vertex -> (bid, robot id); change it via _set_best/_drop
        self._owned = set()         # vertices whose best bidder is this robot (its tasks)
        self._center = (None, None)  # (tasks tuple, its centre), recomputed when tasks change
        self.won = None             # target after the current one, won at auction
        self.excluded = set()
        self.auction_token = 0

    # -- knowledge --------------------------------------------------------------------------
    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.gi = IdlenessEstimate(self.graph.n, 2.0 * self.graph.n, now)
        self.gi.values[start_vertex] = 0.0

    @property
    def tasks(self):
        return sorted(self._owned)

    def _set_best(self, v, bid, robot):
        self.best_bid[v] = (bid, robot)
        if robot == self.id:
            self._owned.add(v)
        else:
            self._owned.discard(v)

    def _drop(self, v):
        self.best_bid.pop(v, None)
        self._owned.discard(v)

    def task_center(self, tasks):
        """The task vertex minimising the summed path costs to all tasks (lowest id on ties),
        recomputed only when the task set changes, as the original."""
        key = tuple(tasks)
        if self._center[0] != key:
            D = self.graph.dist
            sums = D[np.ix_(key, key)].sum(axis=1)
            self._center = (key, key[int(np.argmin(sums))])
        return self._center[1]

    def utility(self, cv, g):
        """U(cv, v) for every vertex v (numpy array)."""
        return (self.p["theta_idleness"] * g
                + self.p["theta_hop"] * self.graph.hops[cv] * self.graph.n
                + self.p["theta_navigation"] * self.graph.dist[cv])

    def bid(self, v):
        if v in (self.next, self.won):
            return 0.0
        tasks = self.tasks
        if tasks:
            center = self.task_center(tasks)
        else:
            center = self.next if self.next is not None else self.current
        return float(self.graph.dist[v, center]) * (1 + len(tasks))

    def record_bid(self, v, bid, robot):
        old = self.best_bid.get(v)
        if old is None or old[0] >= (1.0 + self.p["hist"]) * bid:
            self._set_best(v, bid, robot)

    # -- decisions --------------------------------------------------------------------------
    def _best_candidate(self, cv, now, exclude):
        u = self.utility(cv, self.gi.advance(now))
        u[~np.isfinite(self.graph.hops[cv])] = -np.inf
        for v in exclude:
            u[v] = -np.inf
        if not np.isfinite(u).any():
            return None
        return int(np.argmax(u))            # first maximum: lowest id on ties

    def choose_next(self, now):
        u = self.current
        if self.won is not None and self.won != u:
            nxt = self.won
        else:
            nxt = self._best_candidate(u, now, {u})
            if nxt is None:             # a one-vertex graph
                nxt = u
        self.won = None
        self._drop(nxt)
        self.gi.advance(now)[nxt] = 0.0
        self.next = nxt
        self.excluded = {nxt, u}
        return nxt

    def on_arrival(self, vertex, now):
        super().on_arrival(vertex, now)
        self.gi.advance(now)[vertex] = 0.0
        self._drop(vertex)

    def send_results(self, now):
        """As the original: the idleness message, then (once the goal is on its way) the
        auction for the target after the next one."""
        self.send(MSG_DTA_IDLENESS, *self.gi.encode(now), self.next)
        self._auction(now)

    # -- auctions ---------------------------------------------------------------------------
    def _auction(self, now):
        cv = self.next
        v = self._best_candidate(cv, now, self.excluded)
        if v is None:
            self.excluded = {cv, self.current}
            v = self._best_candidate(cv, now, self.excluded)
            if v is None:
                return
        self.excluded.add(v)
        b = self.bid(v)
        self.record_bid(v, b, self.id)
        self.auction_token += 1
        token = self.auction_token
        self.send(MSG_SSI_TASK_REQUEST, v, min(int(b), INT16_MAX))
        wait = min(self.p["timeout"], 1.0 + 0.1 * len(self.tasks))
        self.driver.call_later(wait, lambda: self._auction_end(token, cv, v))

    def _auction_end(self, token, cv, v):
        if token != self.auction_token or self.next != cv:
            return                      # superseded by a newer auction
        now = self.driver.now()
        g = self.gi.advance(now)
        best = self.best_bid.get(v, (0.0, self.id))
        if best[1] == self.id:
            self.won = v
            return
        mean, sd = float(np.mean(g)), float(np.std(g))
        if self.graph.hops[cv, v] <= 1 and g[v] > mean + 2 * sd and best[0] != 0:
            self.won = v
            return
        self._auction(now)

    def on_message(self, data, now):
        if self.gi is None or len(data) < 2:
            return
        kind = data[1]
        if kind == MSG_DTA_IDLENESS:
            dec = decode_idleness(data, self.graph.n)
            if dec is not None:
                self.gi.merge(dec[0], now)
        elif kind in (MSG_SSI_TASK_REQUEST, MSG_SSI_BID) and len(data) >= 4:
            v, b = data[2], float(data[3])
            if not 0 <= v < self.graph.n:
                return
            self.record_bid(v, b, data[0])
            if kind == MSG_SSI_TASK_REQUEST:
                mine = self.bid(v)
                self.record_bid(v, mine, self.id)
                if self.best_bid[v][1] == self.id:
                    self.send(MSG_SSI_BID, v, min(int(mine), INT16_CAP))
