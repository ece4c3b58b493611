"""IC, Idleness Coordinator (the "Cognitive Coordinated" architecture of Machado, Ramalho,
Zucker, Drogoul, "Multi-agent patrolling: an empirical analysis of alternative
architectures", MABS 2002, LNCS 2581).

A central coordinator knows every visit and, whenever a robot reaches its goal, sends it to
the vertex of highest idleness that no other robot is heading to. Distance plays no part in
the choice (it does in HPCC, a later variant); the robot walks there along the shortest
path, each vertex on the way a goal of its own.

Here the coordinator is not a node of its own: it is hosted by the lowest-id robot this
robot believes alive (itself included), so the algorithm is one strategy and its messages go
through the same communication model as every other. Messages:

- ``[i, 54, v, ask]`` after every visit: ``ask`` 1 when v is robot i's goal and it asks for
  the next one (sent when it decides, the visit's report follows), 0 for a vertex on its
  way or the host's own visit. Every robot records the visit (``last_visit[v] = now``).
- ``[h, 55, r, g]``: robot r heads to g. The host answers each request with it, in the
  order the requests arrive; the host announces its own goals so; a robot that gave up
  waiting announces its own choice so. Every robot keeps the last goal of each robot, so a
  robot that becomes host knows what is taken.

The rule (:meth:`IdlenessCoordinator.assign`): candidates are the vertices not assigned to
another robot and not the requester's own vertex (if that leaves none: every vertex); the
goal is the one of highest idleness ``now - last_visit`` by the host's table, ties broken
uniformly with ``rng``. A requester waits (``next_vertex`` returns None, asked again every
0.5 s); after ``ic_timeout`` s (default 5) without an answer it applies the same rule to its
own table and announces its choice. A silent host (``teammate_timeout``, attrition runs) is
given up, and the next lowest id takes over; a teammate heard again rejoins (a repaired
robot 0 is host again).
"""
from typing import Dict, List

from patrolling_sim.algorithms.base import PatrolStrategy, argmax_random, register
from patrolling_sim.common.protocol import MSG_IC_ASSIGN, MSG_IC_REQUEST

#: default s a robot waits for the coordinator's answer before it chooses alone
IC_TIMEOUT = 5.0


@register
class IdlenessCoordinator(PatrolStrategy):
    name = "IC"

    def __init__(self, ctx):
        super().__init__(ctx)
        self.timeout = float(ctx.params.get("ic_timeout", IC_TIMEOUT))
        self.algorithm_params = f"{self.timeout:g}"
        self.alive = set(range(max(ctx.team_size, self.id + 1)))
        self.assigned: Dict[int, int] = {}      # robot -> goal it was sent to
        self.path: List[int] = []               # remaining steps to the goal
        self.waiting_since = None               # time of the pending request
        self.outbox: List[tuple] = []           # to send after the decision
        self.fallbacks = 0                      # decisions taken without an answer

    @property
    def host(self) -> int:
        """The robot hosting the coordinator: the lowest id believed alive."""
        return min(self.alive | {self.id})

    # -- the coordinator's rule -------------------------------------------------------
    def assign(self, robot: int, at: int, now: float) -> int:
        """The goal for ``robot`` standing on ``at``: the highest idleness among the vertices
        no other robot is assigned to, ``at`` excluded (unless nothing else is left); ties
        with ``rng``. Records the assignment."""
        self.assigned.pop(robot, None)
        taken = set(self.assigned.values())
        cands = [v for v in range(self.graph.n) if v not in taken and v != at]
        if not cands:
            cands = [v for v in range(self.graph.n) if v != at] or [at]
        lv = self.last_visit
        goal = argmax_random(cands, lambda v: now - lv[v], self.rng)
        self.assigned[robot] = goal
        return goal

    # -- deciding ---------------------------------------------------------------------
    def next_vertex(self, now):
        if self.path:                   # on the way: the next step
            self.next = self.path.pop(0)
            self.outbox.append((MSG_IC_REQUEST, self.current, 0))
            return self.next
        u = self.current
        if self.host == self.id:
            goal = self.assign(self.id, u, now)
            self.outbox += [(MSG_IC_REQUEST, u, 0), (MSG_IC_ASSIGN, self.id, goal)]
            return self._head_to(goal)
        if not getattr(self.driver, "accepts_pending_decision", True):
            return self._alone(now)
        if self.waiting_since is None:
            self.waiting_since = now
            self.send(MSG_IC_REQUEST, u, 1)
            return None
        if now - self.waiting_since >= self.timeout:
            return self._alone(now)
        return None

    def _alone(self, now):
        """No answer: the coordinator's rule on this robot's own table, announced."""
        self.waiting_since = None
        self.fallbacks += 1
        goal = self.assign(self.id, self.current, now)
        self.outbox.append((MSG_IC_ASSIGN, self.id, goal))
        return self._head_to(goal)

    def _head_to(self, goal):
        """The first step of the shortest path to ``goal`` (the goal itself if it is here)."""
        steps = self.graph.path(self.current, goal)[1:] if goal != self.current else [goal]
        self.path = steps[1:]
        self.next = steps[0]
        return self.next

    def choose_next(self, now):
        """Used by the base class's goal-failure rule only: the coordinator's rule on the
        own table."""
        return self.assign(self.id, self.current, now)

    def on_goal_failed(self, vertex, now):
        self.path = []
        v = super().on_goal_failed(vertex, now)
        self.assigned[self.id] = v
        self.outbox.append((MSG_IC_ASSIGN, self.id, v))
        return self._head_to(v)

    def send_results(self, now):
        out, self.outbox = self.outbox, []
        for payload in out:
            self.send(*payload)

    # -- messages ---------------------------------------------------------------------
    def on_message(self, data, now):
        if len(data) < 4 or data[1] not in (MSG_IC_REQUEST, MSG_IC_ASSIGN):
            return
        sender = int(data[0])
        self.alive.add(sender)
        a, b = int(data[2]), int(data[3])
        if data[1] == MSG_IC_REQUEST:
            if not 0 <= a < self.graph.n:
                return
            self.last_visit[a] = max(self.last_visit[a], now)
            if b == 1:
                self.assigned.pop(sender, None)
                if self.host == self.id:
                    goal = self.assign(sender, a, now)
                    self.send(MSG_IC_ASSIGN, sender, goal)
            return
        if not 0 <= b < self.graph.n:
            return
        self.assigned[a] = b
        if a == self.id and self.waiting_since is not None:
            self.waiting_since = None
            self.driver.redirect(self._head_to(b))

    def on_teammate_silent(self, robot_id, now):
        self.alive.discard(robot_id)
        self.assigned.pop(robot_id, None)

    def on_repair(self, now):
        self.waiting_since = None
        self.path = []
        self.outbox = []
