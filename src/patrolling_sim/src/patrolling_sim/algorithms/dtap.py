"""DTAP, DTA with sequential single-item auctions and partition-based bids (``DTASSIPart``;
Farinelli, Iocchi, Nardi, Autonomous Robots 41(6), 2017).

Every robot keeps a global idleness estimate ``gi`` (2V s at start, ageing, merged with the
teammates' type-40 messages by taking the minimum), the best known bid per vertex and its
*tasks*: the vertices whose best bid is its own. It decides one target ahead, as the original:

- at start it auctions its first target from the start vertex, and sends its first goal (and
  its first visit report) only when that auction is over;
- on reaching its target it heads for the target it won meanwhile (its estimate of that
  vertex set to 0), reports the visit, broadcasts ``[id, 40, I_0..I_{V-1}, next]``, sends
  the goal, and auctions the target after it, from ``cv`` = the new target. A robot that
  arrives while that auction still runs stays where it is, unreported, until it ends (the
  original's main loop is blocked in the auction); the life cycle asks again
  (``next_vertex`` returns None meanwhile) and the end of the auction releases it at once.

One auction from cv: candidates exclude cv and the current vertex; take the first maximum of
``U(cv, v) = theta_idleness * gi[v] + theta_hop * hops(cv, v) * V`` (hops counted on the
cost-shortest path, as the original's Dijkstra returns it), store its own bid without
hysteresis and broadcast ``[id, 41, v, bid]``; teammates record it, compute and record theirs
and reply ``[id, 42, v, best]`` if they now hold the best bid. After
``min(timeout, 1 + 0.1 * |tasks|)`` s: won if this robot holds the best bid (its tasks are
then refreshed); also taken, without becoming a task, if v is at most one hop from cv, its
estimate exceeds mean + 2 SD of all estimates and its best bid is not 0; otherwise the next
candidate is auctioned (once every vertex was tried, only the current vertex stays excluded).

Bid (partition-based): 0 if v is already the next target or the one after; else
``pathcost(v, center) * (1 + |tasks|)``. The centre starts at the start vertex and is
recomputed whenever the task set changes: the current vertex or a task (other than the old
centre) with the smallest summed path cost to all tasks, the current vertex winning ties. A
recorded best bid is replaced by a new one when ``stored >= (1 + hist) * new``. Bids and
estimates above the int16 range are sent as 32000. Parameters from
``params/DTA/DTASSI.params`` (timeout 3, theta_idleness 1, theta_navigation 0 -- unused, as in
the original --, theta_hop -2, threshold 0 -- unused --, hist 0).

DTASSI (:mod:`patrolling_sim.algorithms.dtassi`) is this agent with another bid and no
partition: it replaces :meth:`DTASSIPart.bid`, :meth:`DTASSIPart.tasks_changed` and
:meth:`DTASSIPart.auction_wait`.

The life cycle (docs/protocol.md) waits for a decision that is pending. A driver that cannot
(a test double declaring ``accepts_pending_decision = False``) gets the best candidate by U at
once instead.
"""
import numpy as np

from patrolling_sim.algorithms.base import PatrolStrategy, register
from patrolling_sim.common.protocol import (INT16_CAP, INT16_MAX, MSG_DTA_IDLENESS, MSG_SSI_BID,
                                            MSG_SSI_TASK_REQUEST)
from patrolling_sim.algorithms.dta_common import (IdlenessEstimate, VersionedDict, decode_seconds,
                                                  dta_params, path_hops)

DEFAULTS = {"timeout": 3.0, "theta_idleness": 1.0, "theta_navigation": 0.0,
            "theta_hop": -2.0, "threshold": 0.0, "hist": 0.0}
#: the stored value of "no bid yet" (any real bid replaces it)
NO_BID = float("inf")
NO_BID_ENTRY = (NO_BID, -1)
#: auction wait: ``min(timeout, AUCTION_BASE_WAIT + AUCTION_WAIT_PER_TASK * |tasks|)`` seconds
AUCTION_BASE_WAIT = 1.0
AUCTION_WAIT_PER_TASK = 0.1
#: greedy exception: an estimate above mean + GREEDY_SD * SD
GREEDY_SD = 2.0


def int16_payload(x):
    """An int payload entry as the original sends it: int(x), values above INT16_MAX as
    INT16_CAP."""
    v = int(x)
    return INT16_CAP if v > INT16_MAX else v


@register
class DTASSIPart(PatrolStrategy):
    name = "DTAP"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.p = dta_params(ctx, "DTASSI", DEFAULTS)
        self.algorithm_params = ",".join(f"{self.p[k]:g}" for k in DEFAULTS)
        self._hist_factor = 1.0 + self.p["hist"]    # a bid replaces one >= factor * it
        self.gi = None
        self.hops = path_hops(self.graph)
        self._hop_rows = {}
        self.best_bid = VersionedDict()     # vertex -> (bid, robot id)
        self.task_set = set()       # vertices whose best bid is this robot's
        self._tasks_of = -1         # best_bid.version the task set was derived from
        self.center = None
        self.won = None             # the target after the next one (next_next)
        self.selected = set()       # candidates excluded in the running auction sequence
        self.auction = None         # (token, cv, v) of the running auction, or None
        self._token = 0
        self._pending = False       # the life cycle waits for our decision
        self._first = True
        self._arrival = None        # reached vertex not yet taken into the tables

    # -- knowledge --------------------------------------------------------------------------
    def prepare(self, start_vertex):
        """The shortest-path table every decision reads, computed before GO (36 ms on
        broughton, i.e. a second of simulated time at x30 if left to the first decision)."""
        self.graph.dist

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.gi = IdlenessEstimate(self.graph.n, 2.0 * self.graph.n, now)
        self.center = start_vertex
        self._start_auction(start_vertex, now)      # the first target

    @property
    def tasks(self):
        return sorted(self.task_set)

    def _advance(self, now):
        """The original's update_global_idleness: age the estimates, zero the current
        vertex's."""
        g = self.gi.advance(now)
        g[self.current] = 0.0
        return g

    def _sum_cost(self, v):
        D = self.graph.dist
        return float(sum(D[v, t] for t in self.task_set))

    def _update_tasks(self):
        if self._tasks_of == self.best_bid.version:
            return                  # the bids did not change: neither would the tasks
        self._tasks_of = self.best_bid.version
        tasks = {v for v, (_, r) in self.best_bid.items() if r == self.id}
        if tasks != self.task_set:
            self.task_set = tasks
            self.tasks_changed()

    def tasks_changed(self):
        """The task set just changed: the partition's centre is recomputed (the current
        vertex or a task other than the old centre with the smallest summed path cost to all
        tasks, the current vertex winning ties). A subclass whose bid needs no centre
        overrides this."""
        best, best_sum = self.current, self._sum_cost(self.current)
        for t in sorted(self.task_set):
            if t != self.center:
                s = self._sum_cost(t)
                if s < best_sum:
                    best, best_sum = t, s
        self.center = best

    def auction_wait(self):
        """Seconds an auction waits for bids: ``min(timeout, 1 + 0.1 * |tasks|)``."""
        return min(self.p["timeout"],
                   AUCTION_BASE_WAIT + AUCTION_WAIT_PER_TASK * len(self.task_set))

    def _hop_terms(self, cv):
        """(theta_hop * hops(cv, .) * V, the vertices unreachable from cv), kept per cv: they
        do not change during a run."""
        t = self._hop_rows.get(cv)
        if t is None:
            t = self._hop_rows[cv] = (self.p["theta_hop"] * self.hops[cv] * self.graph.n,
                                      ~np.isfinite(self.hops[cv]))
        return t

    def utility(self, cv, g):
        """U(cv, v) for every vertex v (numpy array)."""
        return self.p["theta_idleness"] * g + self._hop_terms(cv)[0]

    def bid(self, v):
        if v in (self.next, self.won):
            return 0.0
        return float(self.graph.dist[v, self.center]) * (1 + len(self.task_set))

    def record_bid(self, v, bid, robot):
        """The original's update_bids: keep the better bid (with hysteresis), refresh tasks."""
        table = self.best_bid
        old = table.get(v, NO_BID_ENTRY)
        if old[0] >= self._hist_factor * bid:
            synced = self._tasks_of == table.version
            table[v] = (bid, robot)
            if synced and (old[1] == self.id) == (robot == self.id):
                self._tasks_of = table.version  # v stays in (or out of) our tasks
        if self._tasks_of != table.version:     # (_update_tasks' own test, inline: most
            self._update_tasks()                # bids change nothing)

    # -- decisions --------------------------------------------------------------------------
    def _select(self, cv, now):
        """First maximum of U over the candidates not yet excluded (reset when exhausted)."""
        if len(self.selected) >= self.graph.n:
            self.selected = {self.current}
        u = self.utility(cv, self.gi.advance(now))
        u[self._hop_terms(cv)[1]] = -np.inf
        for v in self.selected:
            u[v] = -np.inf
        v = int(np.argmax(u)) if np.isfinite(u).any() else cv
        self.selected.add(v)
        return v

    def choose_next(self, now):
        """Fallback decision (goal failure, or no waiting life cycle): the best candidate by
        U from the current vertex."""
        g = self._advance(now)
        u = self.utility(self.current, g)
        u[self._hop_terms(self.current)[1]] = -np.inf
        u[self.current] = -np.inf
        return int(np.argmax(u)) if np.isfinite(u).any() else self.current

    def next_vertex(self, now):
        if self.won is None:
            if getattr(self.driver, "accepts_pending_decision", True):
                self._pending = True
                return None
            self.auction = None                 # no one waits: decide now
            self._apply_arrival(now)
            self.won = self.choose_next(now)
        self._apply_arrival(now)
        return self._take_won(now)

    def _take_won(self, now):
        nxt = self.won
        if not self._first:
            self.gi.advance(now)[nxt] = 0.0     # the active target looks visited
        self._first = False
        self.next = nxt
        return nxt

    def on_arrival(self, vertex, now):
        """Kept until the decision: the original updates its tables only when its blocked
        loop gets to the reached goal, i.e. after the running auction."""
        self._arrival = vertex

    def _apply_arrival(self, now):
        if self._arrival is not None:
            self._advance(now)                  # zeroes the vertex we leave
            PatrolStrategy.on_arrival(self, self._arrival, now)
            self._arrival = None

    def send_results(self, now):
        """As the original: the idleness message, then (the goal being on its way) the
        auction for the target after the next one."""
        self.send(MSG_DTA_IDLENESS, *self.gi.encode(now), self.next)
        self.won = None
        self._start_auction(self.next, now)

    # -- auctions ---------------------------------------------------------------------------
    def _start_auction(self, cv, now):
        self._advance(now)
        self.selected = {self.current, cv}
        self._auction_round(cv, now)

    def _auction_round(self, cv, now):
        v = self._select(cv, now)
        b = self.bid(v)
        self.best_bid[v] = (b, self.id)         # forced: no hysteresis, tasks not refreshed
        self._token += 1
        token = self._token
        self.auction = (token, cv, v)
        self.send(MSG_SSI_TASK_REQUEST, v, int16_payload(b))
        self.driver.call_later(self.auction_wait(), lambda: self._auction_end(token))

    def _auction_end(self, token):
        if self.auction is None or self.auction[0] != token:
            return                              # superseded
        _, cv, v = self.auction
        now = self.driver.now()
        best = self.best_bid.get(v, NO_BID_ENTRY)
        if best[1] == self.id:
            self._update_tasks()
        elif not self._greedy(cv, v, best, now):
            self._auction_round(cv, now)
            return
        self.auction = None
        self.won = v
        if self._pending:
            self._pending = False
            self._apply_arrival(now)
            self.driver.redirect(self._take_won(now))

    def _greedy(self, cv, v, best, now):
        g = self.gi.advance(now)
        return (self.hops[cv, v] <= 1 and g[v] > float(np.mean(g)) + GREEDY_SD * float(np.std(g))
                and best[0] != 0)

    def on_repair(self, now):
        """Back after a failure: the running auction's deadline died with the robot, so the
        auction starts a new round (a fresh request and deadline)."""
        if self.auction is not None:
            self._auction_round(self.auction[1], now)

    def on_teammate_silent(self, robot_id, now):
        """A silent teammate's won tasks are open again: its best bids are forgotten, so the
        next auctions re-assign those vertices (and they count in no one's task set)."""
        lost = [v for v, (_, r) in self.best_bid.items() if r == robot_id]
        for v in lost:
            del self.best_bid[v]
        if lost:
            self._update_tasks()

    def on_message(self, data, now):
        if self.gi is None or len(data) < 2:
            return
        kind = data[1]
        if kind == MSG_DTA_IDLENESS:
            dec = decode_seconds(data, self.graph)
            if dec is not None:
                self.gi.merge_seconds(dec[0], now)
        elif kind in (MSG_SSI_TASK_REQUEST, MSG_SSI_BID) and len(data) >= 4:
            v, b = data[2], float(data[3])
            if not 0 <= v < self.graph.n:
                return
            self.record_bid(v, b, data[0])
            if kind == MSG_SSI_TASK_REQUEST:
                self.record_bid(v, self.bid(v), self.id)
                best = self.best_bid[v]
                if best[1] == self.id:
                    self.send(MSG_SSI_BID, v, int16_payload(best[0]))
