"""CR, Conscientious Reactive: go to the neighbour this robot visited least recently
(its own, local idleness; Machado et al. 2002)."""
from patrolling_sim.algorithms.base import PatrolStrategy, argmax_random, register


@register
class ConscientiousReactive(PatrolStrategy):
    name = "CR"

    def choose_next(self, now):
        nbrs = self.graph.neighbor_ids(self.current)
        return argmax_random(nbrs, lambda w: self.idleness[w], self.tie_rng)
