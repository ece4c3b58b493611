"""RWF, Reactive With Flags (Machado, Ramalho, Zucker, Drogoul, MABS 2002): stigmergy. The
vertices carry flags that robots write and read; a robot reads only the flag of the vertex it
stands on and goes to the neighbour that flag shows as visited longest ago.

The flag of vertex v: a time per neighbour w, the latest moment a robot was known *at v* to
have been at w or to have set off for w, and v's own last visit. Robots write it
(:class:`FlagBoard`) when they

* reach v: v's visit time, and for the neighbour u they came from, the time they visited u
  (the news a robot carries along the edge it travelled);
* leave v for w: the departure time, on w's entry (w is about to be visited).

A robot on v chooses ``argmin_w flag_v[w]`` over the neighbours of v (never marked: time 0;
ties with ``ctx.rng``): :func:`oldest_neighbour` takes that one flag and nothing else.

The framework has no shared storage, so the environment is emulated: every robot keeps a
replica of all flags, applies its own writes at once and broadcasts them on /results
(``[id, 52, v, t, prev, t_prev]`` on a visit, ``[id, 53, v, next, t]`` on a departure);
receivers apply them to their replicas (a write keeps the later time). Writes therefore go
through the communication model like every algorithm message: a lost write is a mark the
receiver's copy of that vertex never shows; a delayed one shows late. docs/algorithms/RWF.md.
"""
from types import MappingProxyType

from patrolling_sim.algorithms.base import PatrolStrategy, argmax_random, register
from patrolling_sim.algorithms.msgtime import HORIZON, decode_time, encode_time
from patrolling_sim.common.protocol import MSG_RWF_DEPART, MSG_RWF_VISIT

#: a carried visit older than this (s) is not written on arrival: its time code could not be
#: restored by the receivers (msgtime.HORIZON), e.g. after a long failure on an edge
CARRY_LIMIT = HORIZON - 100.0


class FlagBoard:
    """One robot's replica of the flags of every vertex: ``flag(v)[w]`` is a time (s).

    Writes keep the later time (:meth:`write`); :meth:`read` hands out one vertex's flag,
    read-only. The strategy reads through :meth:`read` only, and only for the vertex it
    stands on (tests replace the board with one that records the reads)."""

    def __init__(self, n: int):
        self.flags = [dict() for _ in range(n)]

    def write(self, v: int, w: int, t: float) -> bool:
        """Mark entry ``w`` of vertex ``v``'s flag with time ``t`` unless it already shows a
        later one; returns whether the flag changed."""
        if t > self.flags[v].get(w, float("-inf")):
            self.flags[v][w] = t
            return True
        return False

    def read(self, v: int):
        """The flag of vertex ``v`` (a read-only mapping neighbour -> time)."""
        return MappingProxyType(self.flags[v])


def on_tick(t):
    """``t`` as the receivers of its time code read it (to the tenth): a robot's own writes
    are kept as its teammates' copies keep them."""
    return decode_time(encode_time(t), t)


def oldest_neighbour(flag, neighbours, rng):
    """The neighbour whose entry in ``flag`` is the oldest (an entry never written counts as
    time 0); ties drawn with ``rng``. Sees nothing but the one flag it is given."""
    return argmax_random(neighbours, lambda w: -flag.get(w, 0.0), rng)


@register
class ReactiveWithFlags(PatrolStrategy):
    name = "RWF"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.board = FlagBoard(self.graph.n)
        self.visit_time = 0.0          # when this robot reached self.current
        self.came_from = None          # (vertex, its visit time) of the vertex left last
        self.outbox = []               # flag writes not broadcast yet
        self.flush_now = False         # a decision outside a visit: broadcast at once

    def _adjacent(self, u, w):
        return u is not None and w is not None and self.graph.arc_cost(u, w) is not None

    # -- flag writes -------------------------------------------------------------------
    def _mark_visit(self, v, now):
        now = on_tick(now)
        self.visit_time = now
        self.board.write(v, v, now)
        prev, t_prev = -1, now
        if self.came_from is not None:
            u, t_u = self.came_from
            if self._adjacent(v, u) and now - t_u < CARRY_LIMIT:
                self.board.write(v, u, t_u)
                prev, t_prev = u, t_u
        self.outbox.append((MSG_RWF_VISIT, v, encode_time(now), prev, encode_time(t_prev)))

    def _mark_departure(self, v, w, now):
        now = on_tick(now)
        self.came_from = (v, self.visit_time)
        if self._adjacent(v, w):
            self.board.write(v, w, now)
            self.outbox.append((MSG_RWF_DEPART, v, w, encode_time(now)))

    def _flush(self):
        for msg in self.outbox:
            self.send(*msg)
        self.outbox = []

    # -- the rule ----------------------------------------------------------------------
    def choose_next(self, now):
        u = self.current
        return oldest_neighbour(self.board.read(u), self.graph.neighbor_ids(u), self.rng)

    # -- life cycle --------------------------------------------------------------------
    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self._mark_visit(start_vertex, now)

    def on_arrival(self, vertex, now):
        super().on_arrival(vertex, now)
        self._mark_visit(vertex, now)

    def next_vertex(self, now):
        v = super().next_vertex(now)
        self._mark_departure(self.current, v, now)
        if self.flush_now:
            self.flush_now = False
            self._flush()
        return v

    def send_results(self, now):
        self._flush()

    def on_goal_failed(self, vertex, now):
        """The base class's choice (it reads the flag of the vertex last reached); the new
        departure is written and broadcast at once."""
        v = super().on_goal_failed(vertex, now)
        self._mark_departure(self.current, v, now)
        self._flush()
        return v

    def on_repair(self, now):
        """Back after a failure: the next departure is broadcast when it is decided."""
        self.flush_now = True

    def on_message(self, data, now):
        n = self.graph.n
        if data[1] == MSG_RWF_VISIT and len(data) >= 6 and 0 <= data[2] < n:
            v = data[2]
            self.board.write(v, v, decode_time(data[3], now))
            if self._adjacent(v, data[4]) and 0 <= data[4] < n:
                self.board.write(v, data[4], decode_time(data[5], now))
        elif data[1] == MSG_RWF_DEPART and len(data) >= 5 and 0 <= data[2] < n:
            if 0 <= data[3] < n and self._adjacent(data[2], data[3]):
                self.board.write(data[2], data[3], decode_time(data[4], now))
