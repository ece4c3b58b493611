"""CBLS, Concurrent Bayesian Learning Strategy (Portugal & Rocha, "Cooperative multi-robot
patrol with Bayesian learning", Autonomous Robots 40(5), 2016).

Each robot keeps, per vertex, the number of visits it knows of ``n[v]`` (own and reported),
the running mean idleness at those visits ``avg[v]`` (updated, as the original, with v's
idleness as last refreshed, then the whole table is refreshed: on every own arrival and every
teammate's report), and a learnt weight per directed arc ``real_hist[u->c]`` (start 1.0,
clamped to [0.5, 2]). The first decision sees an all-zero table. At vertex u:

1. candidates = neighbours no teammate announced as its next goal (all if none remain);
   a single candidate is taken directly;
2. prior of candidate c: its expected idleness ``cur[c] = (avg[c]*n[c] + idl[c]) / (n[c]+1)``,
   blended 0.75/0.25 with the best ``cur`` among c's own free neighbours (look-ahead; a
   dead end, or every neighbour of u taken, uses cur[c] only; so does a look-ahead maximum
   <= 0.001); priors are normalised (uniform if their sum is <= 0.001);
3. posterior = prior * hist[u->c] (hist = real_hist normalised over u's arcs); argmax; ties
   go to the cheapest edge, and among equally cheap ones to the last in neighbour order (the
   original's loop keeps the last ``<=``) -- no random draw;
4. learning, on reaching the chosen vertex, on the table refreshed at that arrival: with H
   the normalised entropy of the posteriors of that decision, the arcs of the decision whose
   targets have the highest idleness are rewarded by +(1-H), those with the lowest punished
   by -(1-H) (punishment wins when both apply).

Robots broadcast ``[id, 32, v, next]`` (SEBS's message id) on reaching v. As the original,
an intention counts only if its sender's id is below the robot's *local* team size: own id + 1,
raised to k + 1 whenever the position of robot k has been heard on /positions (the driver's
``team_pos``; see docs/fidelity.md). A driver that hears no positions (no ``team_pos``
attribute) gives the full team size.
"""
import math

from patrolling_sim.algorithms.base import PatrolStrategy, register
from patrolling_sim.common.protocol import MSG_SEBS_REACHED

HIST_MIN, HIST_MAX = 0.5, 2.0
#: weight of a candidate's own expected idleness in the look-ahead prior
W_FIRST_LAYER = 0.75
#: below this, a look-ahead maximum or a prior sum counts as zero
LOOKAHEAD_EPS = 0.001


@register
class ConcurrentBayesianLearning(PatrolStrategy):
    name = "CBLS"

    def __init__(self, ctx):
        super().__init__(ctx)
        n = self.graph.n
        self.nvis = [0] * n
        self.avg = [0.0] * n
        self.real_hist = {(u, w): 1.0 for u in range(n) for w in self.graph.neighbor_ids(u)}
        self.intention = {}
        self.decision = None            # (u, candidates, H) of the last decision with a choice
        self.local_team_size = self.id + 1  # the original's TEAMSIZE, raised by positions heard

    def start(self, start_vertex, now):
        """As the original's CBLS agent: last visits at the agent's start time (the start
        vertex 0.1 s later), one visit counted on the start vertex, the idleness table all
        zero until the first event."""
        super().start(start_vertex, now)
        self.last_visit = [now] * self.graph.n
        self.last_visit[start_vertex] = now + 0.1
        self.nvis[start_vertex] = 1

    # -- shared knowledge -------------------------------------------------------------------
    def _record_visit(self, v, now):
        """A visit of v (own or reported), then the whole table refreshed, as the original:
        the running mean takes the idleness of v *as last refreshed* (not now - last visit)."""
        self.nvis[v] += 1
        self.avg[v] = (self.avg[v] * (self.nvis[v] - 1) + self.idleness[v]) / self.nvis[v]
        self.last_visit[v] = now
        self.update_idleness(now)

    def cur(self, v):
        return (self.avg[v] * self.nvis[v] + self.idleness[v]) / (self.nvis[v] + 1)

    def hist(self, u, c):
        total = sum(self.real_hist[(u, w)] for w in self.graph.neighbor_ids(u))
        return self.real_hist[(u, c)] / total

    def team_size_heard(self):
        """The original's local TEAMSIZE: own id + 1, raised (never lowered) to k + 1 by
        every robot k whose position was heard (the driver's ``team_pos`` keys)."""
        heard = getattr(self.driver, "team_pos", None)
        if heard is None:
            return self.ctx.team_size
        if heard:
            self.local_team_size = max(self.local_team_size, max(heard) + 1)
        return self.local_team_size

    def _taken(self):
        size = self.team_size_heard()
        return {t for r, t in self.intention.items() if r != self.id and r < size}

    # -- decision ---------------------------------------------------------------------------
    def choose_next(self, now):
        """On the table as last refreshed (the original does not refresh it to decide)."""
        u = self.current
        nbrs = self.graph.neighbor_ids(u)
        taken = self._taken()
        cands = [w for w in nbrs if w not in taken]
        all_occupied = not cands
        cands = cands or nbrs
        if len(cands) == 1:
            self.decision = None
            return cands[0]
        priors = []
        for c in cands:
            m = 0.0
            if self.graph.degree(c) > 1 and not all_occupied:
                m = max((self.cur(w) for w in self.graph.neighbor_ids(c) if w not in taken),
                        default=0.0)
            prior = self.cur(c) if m <= LOOKAHEAD_EPS else \
                W_FIRST_LAYER * self.cur(c) + (1.0 - W_FIRST_LAYER) * m
            priors.append(prior)
        total = sum(priors)
        priors = [p / total for p in priors] if total > LOOKAHEAD_EPS else \
            [1.0 / len(cands)] * len(cands)
        post = [p * self.hist(u, c) for p, c in zip(priors, cands)]
        best = max(post)
        ties = [c for p, c in zip(post, cands) if p >= best - 1e-12 * max(1.0, best)]
        # the original's tie-break: the cheapest edge, the last such tie in neighbour order
        cheapest = min(self.graph.arc_cost(u, c) for c in ties)
        choice = [c for c in ties if self.graph.arc_cost(u, c) == cheapest][-1]
        s = sum(post)
        H = 0.0
        if s > 0:
            probs = [p / s for p in post if p > 0]
            H = min(1.0, -sum(p * math.log2(p) for p in probs) / math.log2(len(cands)))
        self.decision = (u, cands, H)
        return choice

    def send_results(self, now):
        self.send(MSG_SEBS_REACHED, self.current, self.next)

    # -- events -----------------------------------------------------------------------------
    def on_arrival(self, vertex, now):
        if vertex == self.current:          # the original updates nothing then
            return
        self.current = vertex
        self._record_visit(vertex, now)     # table refreshed before learning
        if self.decision is not None:
            self._learn()

    def _learn(self):
        u, cands, H = self.decision
        r = 1.0 - H
        idl = {c: self.idleness[c] for c in cands}
        hi, lo = max(idl.values()), min(idl.values())
        for c in cands:
            delta = 0.0
            if idl[c] >= hi:
                delta = r
            if idl[c] <= lo:
                delta = -r
            self.real_hist[(u, c)] = min(HIST_MAX, max(HIST_MIN, self.real_hist[(u, c)] + delta))
        self.decision = None

    def on_message(self, data, now):
        if len(data) >= 4 and data[1] == MSG_SEBS_REACHED and 0 <= data[2] < self.graph.n \
                and self.ctx.team_size > 1:
            self._record_visit(data[2], now)
            self.intention[data[0]] = data[3]

    def on_teammate_silent(self, robot_id, now):
        """A silent teammate no longer takes its announced vertex out of the candidates."""
        self.intention.pop(robot_id, None)
