"""RAND: go to a uniformly random neighbour (Machado et al. 2002)."""
from patrolling_sim.algorithms.base import PatrolStrategy, register


@register
class RandomStrategy(PatrolStrategy):
    name = "RAND"

    def choose_next(self, now):
        return self.tie_rng.choice(self.graph.neighbor_ids(self.current))
