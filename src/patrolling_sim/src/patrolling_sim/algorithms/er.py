"""ER, Expected Reactive (Yan and Zhang, Int. J. Adv. Robot. Syst. 2016,
doi 10.1177/1729881416663666): a reactive rule on the idleness each neighbour is *expected*
to have when this robot gets there, given where its teammates said they are going.

Each robot broadcasts, after every visit, the vertex it reached, its next goal and its
expected arrival there ``[id, 50, v, next, eta]`` (``[id, 51, next, eta]`` for a new goal
without a visit). A robot on vertex u scores every neighbour w with

* ``tau(w) = max(d(u, w), edge_min) / speed``: the travel time estimate (d in metres, the
  shortest path), and ``t_a = now + tau(w)``: the expected arrival;
* ``E(w) = min(t_a - last_visit[w], |t_a - eta_j| for every teammate j heading to w with
  eta_j >= now)``: the expected idleness at the arrival, i.e. the time between this robot's
  arrival and the nearest other visit, the last known one or an announced one on either
  side of it (a teammate that gets there first leaves little to gain; one that gets there
  just after would make this visit redundant);
* utility ``E(w) / tau(w)``;

and goes to the neighbour of highest utility (ties drawn with ``ctx.rng``). A received visit
counts as a visit at its arrival time (as SEBS). docs/algorithms/ER.md.
"""
import math

from patrolling_sim.algorithms.base import PatrolStrategy, argmax_random, register
from patrolling_sim.algorithms.msgtime import decode_time, encode_time
from patrolling_sim.common.protocol import MSG_ER_INTENTION, MSG_ER_VISIT


@register
class ExpectedReactive(PatrolStrategy):
    name = "ER"

    def __init__(self, ctx):
        super().__init__(ctx)
        p = ctx.params
        #: m/s assumed for every robot's travel time estimate (graph mode's and the abstract
        #: world's speed by default)
        self.speed = float(p.get("speed", 1.0))
        #: shortest distance (m) used in the estimate (no near-zero travel times)
        self.edge_min = float(p.get("edge_min", 1.0))
        if self.speed <= 0 or self.edge_min <= 0:
            raise ValueError("ER: speed and edge_min must be positive")
        self.algorithm_params = f"{self.speed:g},{self.edge_min:g}"
        self.intention = {}         # teammate id -> (vertex, expected arrival time)
        self.eta = None             # own expected arrival at self.next
        self.announce = False       # a goal chosen outside a visit is to be broadcast

    # -- the rule ----------------------------------------------------------------------
    def travel_time(self, u, w):
        """Estimated seconds from vertex u to vertex w (edge_min's if w is unreachable)."""
        metres = float(self.graph.dist[u, w]) * self.graph.resolution
        if not math.isfinite(metres):
            metres = self.edge_min
        return max(metres, self.edge_min) / self.speed

    def expected_idleness(self, w, arrival, now):
        """E(w) for an arrival at time ``arrival``: the time since the last known visit of w,
        cut down to the gap to the nearest pending teammate arrival at w."""
        e = arrival - self.last_visit[w]
        for v, eta in self.intention.values():
            if v == w and eta >= now:
                e = min(e, abs(arrival - eta))
        return e

    def utility(self, u, w, now):
        tau = self.travel_time(u, w)
        return self.expected_idleness(w, now + tau, now) / tau

    def choose_next(self, now):
        u = self.current
        w = argmax_random(self.graph.neighbor_ids(u), lambda x: self.utility(u, x, now),
                          self.rng)
        self.eta = now + self.travel_time(u, w)
        return w

    # -- life cycle --------------------------------------------------------------------
    def next_vertex(self, now):
        v = super().next_vertex(now)
        if self.announce:
            self.announce = False
            self.send(MSG_ER_INTENTION, v, encode_time(self.eta))
        return v

    def send_results(self, now):
        self.send(MSG_ER_VISIT, self.current, self.next, encode_time(self.eta))

    def on_goal_failed(self, vertex, now):
        """The base class's choice, announced as the new goal ``[id, 51, v, eta]``."""
        v = super().on_goal_failed(vertex, now)
        self.eta = now + self.travel_time(self.current, v)
        self.send(MSG_ER_INTENTION, v, encode_time(self.eta))
        return v

    def on_repair(self, now):
        """Back after a failure: the next decision is announced (no visit report comes)."""
        self.announce = True

    def on_message(self, data, now):
        n = self.graph.n
        if data[1] == MSG_ER_VISIT and len(data) >= 5 and 0 <= data[2] < n:
            self.last_visit[data[2]] = now
            if 0 <= data[3] < n:
                self.intention[data[0]] = (data[3], decode_time(data[4], now))
        elif data[1] == MSG_ER_INTENTION and len(data) >= 4 and 0 <= data[2] < n:
            self.intention[data[0]] = (data[2], decode_time(data[3], now))

    def on_teammate_silent(self, robot_id, now):
        """A silent teammate's announced arrival is forgotten (it expires at its time
        anyway; this also covers one announced far ahead)."""
        self.intention.pop(robot_id, None)
