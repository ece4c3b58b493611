"""GBS, Greedy Bayesian Strategy (Portugal & Rocha).

Each neighbour w of the current vertex u gets a gain ``g = idl[w] / max(c(u,w), edge_min)``
and the probability ``P = G1 * exp(ln(1/G1) * g / G2)`` (1 if ``g >= G2``); the robot moves
to the argmax. Idleness is shared: every robot broadcasts ``[id, 31, v]`` when it reaches v,
and a receiver treats v as visited now. G1, G2 and edge_min depend on the map and the team
size (the original's calibrated table below): edge_min is the map's value whatever the team
size; G2 is the table's value for that team size, 100 for team sizes the table lacks; maps
outside the table use G2 100 and edge_min 1. G1 is 0.1 everywhere. All three can be
overridden with the ``G1``/``G2``/``edge_min`` parameters.
"""
import math

from patrolling_sim.algorithms.base import PatrolStrategy, argmax_random, register
from patrolling_sim.common.protocol import MSG_GBS_REACHED

G1_DEFAULT, G2_DEFAULT, EDGE_MIN_DEFAULT = 0.1, 100.0, 1.0
#: map -> (edge_min, {team size: G2}) from the original implementation
GBS_TABLE = {
    "grid": (1.0, {1: 20.54, 2: 17.70, 4: 11.15, 6: 10.71, 8: 10.29, 12: 9.13}),
    "example": (20.0, {1: 220.0, 2: 180.5, 4: 159.3, 6: 137.15, 8: 126.1, 12: 126.1}),
    "cumberland": (50.0, {1: 152.0, 2: 100.4, 4: 80.74, 6: 77.0, 8: 63.5, 12: 63.5}),
}


def gbs_params(map_name, team_size):
    """(G1, G2, edge_min) for a map and team size."""
    edge_min, table = GBS_TABLE.get(map_name, (EDGE_MIN_DEFAULT, {}))
    return G1_DEFAULT, table.get(team_size, G2_DEFAULT), edge_min


def gbs_probability(gain, g1, g2):
    if gain >= g2:
        return 1.0
    return g1 * math.exp(math.log(1.0 / g1) * gain / g2)


@register
class GreedyBayesian(PatrolStrategy):
    name = "GBS"

    def __init__(self, ctx):
        super().__init__(ctx)
        p = ctx.params
        g1, g2, em = gbs_params(ctx.map_name, ctx.team_size)
        self.g1 = float(p.get("G1", g1))
        self.g2 = float(p.get("G2", g2))
        self.edge_min = float(p.get("edge_min", em))

    def probability(self, u, w):
        gain = self.idleness[w] / max(self.graph.arc_cost(u, w), self.edge_min)
        return gbs_probability(gain, self.g1, self.g2)

    def choose_next(self, now):
        u = self.current
        return argmax_random(self.graph.neighbor_ids(u), lambda w: self.probability(u, w),
                             self.tie_rng)

    def send_results(self, now):
        self.send(MSG_GBS_REACHED, self.current)

    def on_message(self, data, now):
        if len(data) >= 3 and data[1] == MSG_GBS_REACHED and 0 <= data[2] < self.graph.n:
            # shared idleness: v counts as visited now (the whole table is refreshed at the
            # next decision, on arrival)
            self.last_visit[data[2]] = now
            self.idleness[data[2]] = 0.0
