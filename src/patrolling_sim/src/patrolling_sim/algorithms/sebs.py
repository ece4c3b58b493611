"""SEBS, State Exchange Bayesian Strategy (Portugal & Rocha, RAS 2013).

GBS's rule (G1 0.1, G2 100, edge_min 1 on every map) weighted by the teammates' intentions:
a neighbour that c > 0 other robots announced as their next goal has its probability
multiplied by ``2^(N-c) / (2^N - 1)``. Robots broadcast ``[id, 32, v, next]`` on reaching v;
receivers treat v as visited now and record the sender's intention.
"""
from patrolling_sim.algorithms.base import PatrolStrategy, argmax_random, register
from patrolling_sim.common.protocol import MSG_SEBS_REACHED
from patrolling_sim.algorithms.gbs import gbs_probability


@register
class StateExchangeBayesian(PatrolStrategy):
    name = "SEBS"
    algorithm_params = "0.1,100"

    def __init__(self, ctx):
        super().__init__(ctx)
        p = ctx.params
        self.g1 = float(p.get("G1", 0.1))
        self.g2 = float(p.get("G2", 100.0))
        self.edge_min = float(p.get("edge_min", 1.0))
        self.intention = {}             # robot id -> announced next vertex

    def probability(self, u, w):
        gain = self.idleness[w] / max(self.graph.arc_cost(u, w), self.edge_min)
        p = gbs_probability(gain, self.g1, self.g2)
        c = sum(1 for r, t in self.intention.items() if t == w and r != self.id)
        if c > 0:
            n = max(self.ctx.team_size, c)
            p *= 2.0 ** (n - c) / (2.0 ** n - 1.0)
        return p

    def choose_next(self, now):
        u = self.current
        return argmax_random(self.graph.neighbor_ids(u), lambda w: self.probability(u, w),
                             self.tie_rng)

    def send_results(self, now):
        self.send(MSG_SEBS_REACHED, self.current, self.next)

    def on_message(self, data, now):
        if len(data) >= 4 and data[1] == MSG_SEBS_REACHED and 0 <= data[2] < self.graph.n:
            self.last_visit[data[2]] = now
            self.idleness[data[2]] = 0.0     # the table is refreshed at the next decision
            self.intention[data[0]] = data[3]

    def on_teammate_silent(self, robot_id, now):
        """A silent teammate (failed, or out of reach) no longer claims its announced vertex:
        its intention stops lowering that vertex's probability."""
        self.intention.pop(robot_id, None)
