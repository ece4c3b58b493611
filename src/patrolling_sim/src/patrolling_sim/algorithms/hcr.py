"""HCR, Heuristic Conscientious Reactive (Almeida et al. 2004).

Score of neighbour w of the current vertex u, with dmax and imax taken over the neighbours:
``(dmax - c(u,w)) / dmax + idl[w] / imax`` (the idleness term is 0 when imax is 0).
Idleness is local: only this robot's own visits count.
"""
from patrolling_sim.algorithms.base import PatrolStrategy, argmax_random, register


@register
class HeuristicConscientiousReactive(PatrolStrategy):
    name = "HCR"

    def choose_next(self, now):
        u = self.current
        nbrs = self.graph.neighbor_ids(u)
        cost = {w: self.graph.arc_cost(u, w) for w in nbrs}
        dmax = max(cost.values())
        imax = max(self.idleness[w] for w in nbrs)

        def score(w):
            s = (dmax - cost[w]) / dmax if dmax > 0 else 0.0
            if imax > 0:
                s += self.idleness[w] / imax
            return s
        return argmax_random(nbrs, score, self.tie_rng)
