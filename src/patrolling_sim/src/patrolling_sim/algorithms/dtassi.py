"""DTASSI, DTA with sequential single-item auctions and tour-cost bids, without a partition
(the original's ``DTASSI``; Farinelli, Iocchi, Nardi, Autonomous Robots 41(6), 2017).

Everything but the bid and the auction wait is DTAP's (:mod:`patrolling_sim.algorithms.dtap`):
the idleness estimate and its type-40 message, the one-ahead decision, the auction sequence
from ``cv`` over the candidates by ``U(cv, v) = theta_idleness * gi[v] + theta_hop * hops(cv, v)
* V``, the request/bid messages 41/42, the best-bid table with hysteresis, the tasks (the
vertices whose best bid is this robot's) and the greedy exception. In the original both agents
share one base class; DTAP only replaces its bid and keeps a task counter.

Bid for vertex v (the cost of a tour through v and all own tasks): 0 if v is already the next
target or the one after. Otherwise the tour starts at the current vertex, goes first to the next
target (the first auction, before there is one: to the task or v with the highest ``U`` from
the current vertex), then repeatedly to the remaining task or v with the highest ``U`` from
where it is (first maximum in vertex order), and back to the current vertex; the bid is the sum
of the shortest-path costs of its legs. No centre, no task count: a robot's tasks are never
weighed as a region.

Auction wait: ``min(timeout, 1)`` s. The original computes ``min(timeout, 1 + 0.1 * n)`` with
a task counter ``n`` that only its partitioned variant updates, so DTASSI's stays 0.

Parameters: ``params/DTA/DTASSI.params``, as DTAP (timeout 3, theta_idleness 1,
theta_navigation 0 -- unused --, theta_hop -2, threshold 0 -- unused --, hist 0).
"""
import numpy as np

from patrolling_sim.algorithms.base import register
from patrolling_sim.algorithms.dtap import AUCTION_BASE_WAIT, DTASSIPart


@register
class DTASSI(DTASSIPart):
    name = "DTASSI"

    def tasks_changed(self):
        """Nothing derived from the task set: the bid reads the set itself."""

    def auction_wait(self):
        """``min(timeout, 1)`` s: the original's task counter stays 0 in this agent."""
        return min(self.p["timeout"], AUCTION_BASE_WAIT)

    def tour(self, v):
        """The tour the bid for ``v`` is the cost of, as a vertex list: the current vertex,
        the next target (if any), then the remaining tasks and ``v`` by decreasing U from
        the vertex before (first maximum in vertex order), and the current vertex again.
        Empty when the bid is 0 (``v`` is the next target or the one after)."""
        if v in (self.next, self.won):
            return []
        g = self.gi.values      # the shift since the last update is common to all: same order
        here = self.current
        route = [here]
        left = np.array(sorted(self.task_set | {v}), dtype=np.intp)
        if self.next is not None:
            route.append(self.next)
            left = left[left != self.next]
        while left.size:
            u = self.utility(route[-1], g)[left]
            k = int(np.argmax(u))
            route.append(int(left[k]))
            left = np.delete(left, k)
        route.append(here)
        return route

    def bid(self, v):
        """The summed shortest-path cost of :meth:`tour`, leg after leg (0 for the next
        target and the one after)."""
        D = self.graph.dist
        route = self.tour(v)
        cost = 0.0
        for a, b in zip(route, route[1:]):
            cost += float(D[a, b])
        return cost
