"""The navigation feedback of the graph world (:mod:`patrolling_sim.graphsim.simulator`), its
one job: at every tick of the FEEDBACK_PERIOD lattice (move_base's 5 Hz) each moving robot publishes
its position and its core evaluates interference against the robots of lower id
(``docs/protocol.md``, "Graph mode"). By default only the ticks and checks that can find an
interference are simulated; the results are those of simulating every tick (a test checks).

:class:`FeedbackTicks` is a mixin of :class:`~patrolling_sim.graphsim.simulator.GraphSimulator`;
it uses the simulator's ``t``, ``cfg``, ``robots``, ``team_pos``, ``_due``, ``_pair_due``,
``_tick``, ``_last_tick``, ``_closing_per_tick``, ``perfect_comm``, ``skip_idle_ticks`` and
:meth:`_share_position`; the run loop calls :meth:`next_tick_time` and :meth:`run_tick`.
"""
import math

from patrolling_sim.agent.core import INTERFERENCE_DIST, INTERFERENCE_PERIOD
from patrolling_sim.graphsim.config import FEEDBACK_PERIOD


def first_tick_at(t):
    """The first k with k * FEEDBACK_PERIOD >= t, as the floats compute it."""
    k = max(0, int(t / FEEDBACK_PERIOD))
    while k * FEEDBACK_PERIOD < t:
        k += 1
    while k > 0 and (k - 1) * FEEDBACK_PERIOD >= t:
        k -= 1
    return k


class FeedbackTicks:
    """Feedback ticks and interference evaluation of the graph world."""

    def wake(self, rid):
        """Robot ``rid`` started a trip: it is due at the first tick not yet run whose time is
        not before now (its first published position), and that tick must be run."""
        if not self.cfg.interference:
            return
        k = max(self._last_tick + 1, first_tick_at(self.t))
        if k < self._due[rid]:
            self._due[rid] = k
        if k < self._tick:
            self._tick = k

    def next_tick_time(self):
        """Sim time of the next feedback tick (inf if none is due). The run loop runs it
        after every event of the same time (arrivals, timers, messages), so the order of a
        tick and an event at the same time does not depend on when either was scheduled."""
        return self._tick * FEEDBACK_PERIOD if self._tick != math.inf else math.inf

    def run_tick(self):
        """Navigation feedback at tick ``k = self._tick`` (time k * FEEDBACK_PERIOD,
        move_base's 5 Hz): every moving robot publishes its position, then evaluates
        interference against the published positions of the robots with a lower id
        (docs/protocol.md, "Graph mode").

        With ``skip_idle_ticks`` (the default; perfect communication) only the work that can
        find something is done (:meth:`_feedback_lazy`); ``skip_idle_ticks = False`` runs
        every tick and asks every core (the definition; a test checks both give the same
        messages)."""
        k = self._tick
        self._last_tick = k
        self._tick = math.inf                     # a trip started during the tick lowers it
        if self.skip_idle_ticks:
            nxt = self._feedback_lazy(k)
        else:
            nxt = self._feedback_full(k)
        if nxt < self._tick:
            self._tick = nxt

    def _feedback_full(self, k):
        t, team = self.t, self.team_pos
        moving = [r for r in self.robots if r.pieces is not None]
        for r in moving:
            team[r.id] = r.xy_at(t)
        if not self.perfect_comm:
            for r in moving:
                self._share_position(r.id, team[r.id])
        for r in moving:
            x, y = team[r.id]
            r.core.on_feedback(r.seq, x, y)
        # nobody moves: no tick until the next trip wakes us
        return k + 1 if any(r.pieces is not None for r in self.robots) else math.inf

    def _feedback_lazy(self, k):
        """Tick ``k`` doing only the work that can find an interference. Each pair of robots
        j < i has a due tick: until then the two cannot be within INTERFERENCE_DIST (no robot
        moves faster than v = ``speed`` x graph.max_stretch() in the plane, so a pair at
        distance d needs at least (d - INTERFERENCE_DIST) / (2 v) s). A moving robot i is due
        at the first due tick of its pairs with lower ids, or at the end of its 10 s quiet
        period. A due robot publishes its position; its due pairs are measured
        (:meth:`_measure_due_pairs`); the core is asked only if one of them is within
        INTERFERENCE_DIST (then the published positions of all its lower ids are brought to
        this tick first, as a full tick has them). A robot starting a trip is due at the next
        tick (:meth:`wake`). Ticks at which no robot is due are not simulated. Returns the
        next tick any moving robot is due (inf if none).

        Due ticks are kept per pair, not per robot: with many robots on a small map some
        robot is near another at almost every tick, and one close pair then costs one
        measurement instead of all of the robot's pairs."""
        t = self.t
        robots, due = self.robots, self._due
        team = self.team_pos
        fresh = {}                                # rid -> position at this tick (moving)
        nxt = math.inf                            # the next tick any moving robot is due
        for r in robots:
            i = r.id
            if r.pieces is None:
                due[i] = math.inf
                continue
            if due[i] > k:
                if due[i] < nxt:
                    nxt = due[i]
                continue
            xy = fresh.get(i)
            if xy is None:
                xy = fresh[i] = team[i] = r.xy_at(t)
            core = r.core
            last = core.last_interference
            if t - last < INTERFERENCE_PERIOD:
                # quiet: nothing to evaluate before the period ends (one tick early, so a
                # rounding of k * FEEDBACK_PERIOD cannot skip the first tick it may act)
                due[i] = max(k + 1, int((last + INTERFERENCE_PERIOD) / FEEDBACK_PERIOD) - 1)
                if due[i] < nxt:
                    nxt = due[i]
                continue
            x, y = xy
            near, first = self._measure_due_pairs(k, i, x, y, fresh)
            if near:
                for j in range(i):                # the core reads every lower id's position
                    rj = robots[j]
                    if rj.pieces is not None and j not in fresh:
                        fresh[j] = team[j] = rj.xy_at(t)
                core.on_feedback(r.seq, x, y)
                # an interference stops it (a later trip wakes it)
                due[i] = k + 1 if r.pieces is not None else math.inf
            else:                                 # robot 0 has no pair: never due
                due[i] = first
            if due[i] < nxt:
                nxt = due[i]
        return nxt

    def _measure_due_pairs(self, k, i, x, y, fresh):
        """Measure the pairs of robot ``i`` (at x, y) with lower ids j due at tick ``k``: a
        moving j publishes its position at this tick (recorded in ``fresh`` and
        ``team_pos``, once per tick), a standing one is where it stands; each such pair's
        next due tick becomes k + max(1, the ticks it needs to close to INTERFERENCE_DIST).
        Returns (near, first): whether a published position is within INTERFERENCE_DIST, and
        the first due tick of all i's pairs (inf if i has none)."""
        t, robots, team = self.t, self.robots, self.team_pos
        d2max = INTERFERENCE_DIST * INTERFERENCE_DIST
        per_tick = self._closing_per_tick
        near = False                              # a published position within reach
        pd = self._pair_due[i]
        first = math.inf                          # the first due tick of i's pairs
        for j in range(i):
            dj = pd[j]
            if dj <= k:
                rj = robots[j]
                if rj.pieces is not None:
                    p = fresh.get(j)
                    if p is None:
                        p = fresh[j] = team[j] = rj.xy_at(t)
                    published = True
                else:
                    p = rj.xy                     # standing: where it stood (published) or
                    published = j in team         # where it starts (not yet published)
                d2 = (p[0] - x) ** 2 + (p[1] - y) ** 2
                if published and d2 <= d2max:
                    near = True
                q = int((math.sqrt(d2) - INTERFERENCE_DIST) / per_tick)
                dj = pd[j] = k + (q if q > 1 else 1)
            if dj < first:
                first = dj
        return near, first
