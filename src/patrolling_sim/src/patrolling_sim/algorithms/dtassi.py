"""DTASSI, DTA with sequential single-item auctions and tour-cost bids, without a partition
(the original's ``DTASSI``; Farinelli, Iocchi, Nardi, Autonomous Robots 41(6), 2017).

Everything but the bid and the auction wait is DTAP's (:mod:`patrolling_sim.algorithms.dtap`):
the idleness estimate and its type-40 message, the one-ahead decision, the auction sequence
from ``cv`` over the candidates by
``U(cv, v) = theta_idleness * gi[v] + theta_hop * hops(cv, v) * V``, the request/bid messages
41/42, the best-bid table with hysteresis, the tasks (the vertices whose best bid is this
robot's) and the greedy exception. In the original both agents
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
from patrolling_sim.algorithms.base import register
from patrolling_sim.algorithms.dtap import AUCTION_BASE_WAIT, DTASSIPart


@register
class DTASSI(DTASSIPart):
    name = "DTASSI"

    def __init__(self, ctx):
        super().__init__(ctx)
        self._hop_lists = {}        # vertex -> theta_hop * hops(vertex, .) * V, as floats

    def tasks_changed(self):
        """Nothing derived from the task set: the bid reads the set itself."""

    def auction_wait(self):
        """``min(timeout, 1)`` s: the original's task counter stays 0 in this agent."""
        return min(self.p["timeout"], AUCTION_BASE_WAIT)

    def tour(self, v):
        """The tour the bid for ``v`` is the cost of, as a vertex list: the current vertex,
        the next target (if any), then the remaining tasks and ``v`` by decreasing U from
        the vertex before (first maximum in vertex order), and the current vertex again.
        Empty when the bid is 0 (``v`` is the next target or the one after).

        Plain Python over the few tasks (a tour visits a handful of vertices; numpy's
        per-call cost dominated at that size): U is computed as in
        :meth:`~patrolling_sim.algorithms.dtap.DTASSIPart.utility`, the same products and
        sums, so the same values."""
        if v in (self.next, self.won):
            return []
        gv = self.gi.values     # the shift since the last update is common to all: same order
        th = self.p["theta_idleness"]
        here = self.current
        route = [here]
        left = sorted(self.task_set | {v})
        if self.next is not None:
            route.append(self.next)
            if self.next in left:
                left.remove(self.next)
        idle = {x: th * gv.item(x) for x in left}
        at = route[-1]
        while left:
            row = self._hop_row(at)
            best_k, best_u = 0, idle[left[0]] + row[left[0]]
            for k in range(1, len(left)):
                u = idle[left[k]] + row[left[k]]
                if u > best_u:
                    best_k, best_u = k, u
            at = left.pop(best_k)
            route.append(at)
        route.append(here)
        return route

    def _hop_row(self, at):
        """``theta_hop * hops(at, .) * V`` as a list of floats, kept per vertex."""
        row = self._hop_lists.get(at)
        if row is None:
            row = (self.p["theta_hop"] * self.hops[at] * self.graph.n).tolist()
            self._hop_lists[at] = row
        return row

    def bid(self, v):
        """The summed shortest-path cost of :meth:`tour`, leg after leg (0 for the next
        target and the one after)."""
        cost = self.graph.dist.item
        route = self.tour(v)
        total = 0.0
        for k in range(len(route) - 1):
            total += cost(route[k], route[k + 1])
        return total
