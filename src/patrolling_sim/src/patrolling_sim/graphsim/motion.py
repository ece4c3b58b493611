"""A robot's body in the graph world (:mod:`patrolling_sim.graphsim.simulator`): a point moving
along the patrol graph (or in straight lines), and the
:class:`~patrolling_sim.agent.core.Effects` its core acts through (``docs/protocol.md``,
"Graph mode")."""
import bisect
import math

from patrolling_sim.agent.core import Effects
from patrolling_sim.graphsim.config import MIN_TRIP


class Robot(Effects):
    """One robot's body in the graph world and the :class:`Effects` its core acts through.

    The body is a point: on vertex ``a`` (``loc = (a, a, 0)``), or a fraction ``f`` along the
    edge a->b (``loc = (a, b, f)``). A trip is a list of straight pieces
    ``(x0, y0, x1, y1, length_m, a, b, f0, f1)`` run at constant speed."""

    def __init__(self, sim, rid, start_vertex):
        self.sim = sim
        self.id = rid
        self.core = None
        self.loc = (start_vertex, start_vertex, 0.0)
        self.xy = sim.vertex_xy[start_vertex]
        self.last_vertex = start_vertex       # last vertex reached (reachability of goals)
        self.goal = None
        self.pieces = None                    # active trip, None when standing still
        self.cum = None                       # cumulative length at the end of each piece
        self.depart = 0.0
        self.duration = 0.0
        self.seq = None                       # the core's sequence number of the trip
        self.token = 0                        # bumps on every stop: stale events ignored

    # -- Effects ------------------------------------------------------------------------------
    def now(self):
        return self.sim.t

    def publish(self, data):
        self.sim.publish(self.id, data)

    def call_later(self, delay, fn):
        self.sim.schedule(self.sim.t + delay, fn)

    def backup(self):
        """Nothing to do: the real manoeuvre moves a robot a few centimetres, a point robot
        on the graph stays where it failed (the core still spends the back-up time)."""

    def clear_costmaps(self):
        """Nothing to do: the graph world has no costmaps."""

    def cancel_goal(self):
        self._stop()

    def send_goal(self, vertex, seq):
        sim = self.sim
        self._stop()
        self.token += 1
        token = self.token
        self.goal, self.seq = vertex, seq
        pieces = self._route(vertex)
        if pieces is None:                     # the graph cannot reach it: navigation fails
            sim.schedule(sim.t, lambda: self._failed(token, seq))
            return
        cum, total = [], 0.0
        for p in pieces:
            total += p[4]
            cum.append(total)
        self.pieces, self.cum, self.depart = pieces, cum, sim.t
        self.duration = max(MIN_TRIP, total / sim.cfg.speed)
        sim.wake(self.id)
        if sim.cfg.goal_fail > 0 and sim.rng.random() < sim.cfg.goal_fail:
            sim.schedule(sim.t + sim.rng.random() * self.duration,
                         lambda: self._failed(token, seq))
        else:
            sim.schedule(sim.t + self.duration, lambda: self._arrived(token, seq))

    # -- motion -------------------------------------------------------------------------------
    def _route(self, goal):
        """Pieces from the current location to ``goal``; None if unreachable."""
        g = self.sim.g
        res = g.resolution
        if not math.isfinite(g.dist[self.last_vertex, goal]):
            return None
        vxy = self.sim.vertex_xy
        if self.sim.cfg.travel == "euclidean":
            x, y = self.xy
            gx, gy = vxy[goal]
            return [(x, y, gx, gy, math.hypot(gx - x, gy - y), None, None, 0.0, 0.0)]
        a, b, f = self.loc
        if a != b and 0.0 < f < 1.0:
            # mid-edge (after a stop): leave by whichever end of the edge is shorter overall
            length = g.arc_cost(a, b) * res
            x, y = self.xy
            via_a = f * length + g.dist[a, goal] * res
            via_b = (1.0 - f) * length + g.dist[b, goal] * res
            if not (math.isfinite(via_a) or math.isfinite(via_b)):
                return None
            if via_b <= via_a:
                end, first = b, (x, y, *vxy[b], (1.0 - f) * length, a, b, f, 1.0)
            else:
                end, first = a, (x, y, *vxy[a], f * length, a, b, f, 0.0)
            return [first] + self._edge_pieces(g.path(end, goal))
        start = b if (a != b and f >= 1.0) else a
        # a trip between two vertices is the same every time: built once per run (the
        # pieces are tuples, never changed; a trip only reads them)
        cache = self.sim.trip_cache
        pieces = cache.get((start, goal), False)
        if pieces is False:
            path = g.path(start, goal)
            pieces = cache[(start, goal)] = None if path is None else self._edge_pieces(path)
        return pieces

    def _edge_pieces(self, path):
        g = self.sim.g
        res = g.resolution
        vxy = self.sim.vertex_xy
        out = []
        for u, w in zip(path, path[1:]):
            (x0, y0), (x1, y1) = vxy[u], vxy[w]
            out.append((x0, y0, x1, y1, g.arc_cost(u, w) * res,
                        u, w, 0.0, 1.0))
        return out

    def _piece_at(self, t):
        """(piece, fraction along it) at time ``t`` of the active trip, None for a trip of
        length 0 (the robot stands where it is until it arrives)."""
        cum = self.cum
        total = cum[-1] if cum else 0.0
        if total <= 0.0:
            return None
        s = (t - self.depart) / self.duration * total
        s = total if s > total else (0.0 if s < 0.0 else s)
        pieces = self.pieces
        k = bisect.bisect_left(cum, s)
        if k >= len(pieces):
            k = len(pieces) - 1
        piece = pieces[k]
        length = piece[4]
        return piece, ((s - (cum[k] - length)) / length if length > 0 else 1.0)

    def position(self, t):
        """(x, y, loc) at time ``t`` of the active trip."""
        at = self._piece_at(t)
        if at is None:
            return self.xy[0], self.xy[1], self.loc
        (x0, y0, x1, y1, _, a, b, f0, f1), r = at
        loc = (a, b, f0 + (f1 - f0) * r) if a is not None else self.loc
        return x0 + (x1 - x0) * r, y0 + (y1 - y0) * r, loc

    def xy_at(self, t):
        """(x, y) at time ``t`` of the active trip: :meth:`position` without the location.
        The feedback tick's hot path, so :meth:`_piece_at`'s arithmetic is written out here
        (the same operations in the same order: the same numbers)."""
        cum = self.cum
        total = cum[-1] if cum else 0.0
        if total <= 0.0:
            return self.xy
        s = (t - self.depart) / self.duration * total
        s = total if s > total else (0.0 if s < 0.0 else s)
        pieces = self.pieces
        k = bisect.bisect_left(cum, s)
        if k >= len(pieces):
            k = len(pieces) - 1
        x0, y0, x1, y1, length = pieces[k][:5]
        r = (s - (cum[k] - length)) / length if length > 0 else 1.0
        return x0 + (x1 - x0) * r, y0 + (y1 - y0) * r

    def _stop(self):
        """Stand still where the robot is now; pending arrival/failure events go stale.
        The robot's last published position is where it stopped."""
        if self.pieces is None:
            return
        x, y, self.loc = self.position(self.sim.t)
        self.xy = (x, y)
        self.pieces = self.cum = None
        self.token += 1
        self.sim.stood(self)                       # last feedback: where it stopped

    def _arrived(self, token, seq):
        if token != self.token:
            return
        v = self.goal
        self.pieces = self.cum = None
        self.token += 1
        self.loc = (v, v, 0.0)
        self.xy = self.sim.vertex_xy[v]
        self.sim.stood(self)                       # last feedback: on the vertex
        self.last_vertex = v
        self.core.on_goal_result(seq, True)

    def _failed(self, token, seq):
        if token != self.token:
            return
        self._stop()
        self.core.on_goal_result(seq, False)
