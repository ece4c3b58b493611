"""When the abstract world holds its clock for the agents' messages (docs/abstract_world.md,
"Message hold"): pure logic, no ROS, wall times passed in by the caller.

After any traffic between the agents (a ``/results`` message, a goal, a cancel) the clock
stands still until the traffic has been quiet for ``quiet`` wall s, so that the messages are
delivered and handled, and their answers sent, before simulated time moves on. A message
that asks the teammates for an answer (a DTA task request: every teammate records it, and
those that now hold the best bid answer with theirs) keeps the clock held until every
teammate has answered or the traffic has been quiet for ``answer_quiet`` wall s (a teammate
whose bid is worse sends nothing, so silence is the only sign that it is done). Each hold
lasts at most ``limit`` wall s; then it is counted as timed out and the clock runs on.
"""
from dataclasses import dataclass

from patrolling_sim.common.protocol import (GO, MONITOR_ID, MSG_INIT, MSG_SSI_BID,
                                            MSG_SSI_TASK_REQUEST, ROBOT_READY)
# a deadline counts as reached within the agents' scheduler's own tolerance
from patrolling_sim.common.timer_heap import TOLERANCE as DEADLINE_TOLERANCE


@dataclass
class HoldCounter:
    """How often and how long the clock was held for one reason."""
    holds: int = 0              # holds started
    timeouts: int = 0           # holds ended by their wall-time bound
    wall: float = 0.0           # wall s the clock stood still

    def as_dict(self):
        return {"holds": self.holds, "timeouts": self.timeouts, "wall": round(self.wall, 3)}


def totals(counters):
    """Status fields summing ``counters`` ({reason: HoldCounter}): ``clock_holds``,
    ``hold_timeouts``, ``held_wall`` and the per-reason figures under ``hold_reasons``."""
    c = list(counters.values())
    return {"clock_holds": sum(x.holds for x in c),
            "hold_timeouts": sum(x.timeouts for x in c),
            "held_wall": round(sum(x.wall for x in c), 3),
            "hold_reasons": {k: v.as_dict() for k, v in counters.items()}}


def awaited_answer(data):
    """(answer type, vertex) of the answers a /results message asks of the teammates, or
    None: a DTA task request ``[id, 41, v, bid]`` is answered by bids ``[id, 42, v, bid]``."""
    if len(data) >= 4 and data[0] >= 0 and data[1] == MSG_SSI_TASK_REQUEST:
        return (MSG_SSI_BID, data[2])
    return None


class MessageHold:
    """The message hold's state. ``note`` records traffic (any thread, under the caller's
    lock); ``wait_until`` (the stepping thread, same lock) says whether the clock may move."""

    def __init__(self, quiet, answer_quiet, limit, team_size):
        if min(quiet, answer_quiet, limit) < 0:
            raise ValueError("the message hold's wall times must be >= 0")
        self.quiet, self.answer_quiet, self.limit = quiet, answer_quiet, limit
        self.team = team_size
        self.counter = HoldCounter()
        self.last = None            # wall time of the last traffic
        self.open = {}              # (answer type, vertex) -> {robots that have to answer}
        self.since = None           # wall time the running hold began
        self.ignore_before = None   # traffic noted up to a timed-out hold's end is done with

    @property
    def enabled(self):
        return self.limit > 0

    def note(self, now, data=None):
        """Traffic at wall time ``now``: a /results message ``data`` or (None) a goal."""
        self.last = now
        if data is None or len(data) < 2:
            return
        ask = awaited_answer(data)
        if ask is not None:
            self.open[ask] = set(range(self.team)) - {data[0]}
        elif len(data) >= 3 and (data[1], data[2]) in self.open:
            left = self.open[(data[1], data[2])]
            left.discard(data[0])
            if not left:
                del self.open[(data[1], data[2])]

    def wait_until(self, now):
        """None if the clock may advance at wall time ``now``, else the wall time to wait
        until (the caller waits at most that long, or until new traffic)."""
        if not self.enabled or self.last is None:
            return None
        if self.since is None:
            if self.ignore_before is not None and self.last <= self.ignore_before:
                return None
            quiet = self.answer_quiet if self.open else self.quiet
            if now - self.last >= quiet:
                self.open.clear()
                return None
            self.since = now
            self.counter.holds += 1
        end = self.since + self.limit
        if now >= end:
            self._finish(now, timed_out=True)
            return None
        quiet = self.answer_quiet if self.open else self.quiet
        if now - self.last >= quiet:
            self._finish(now, timed_out=False)
            return None
        return min(end, self.last + quiet)

    def _finish(self, now, timed_out):
        self.counter.wall += now - self.since
        self.counter.timeouts += timed_out
        self.since = None
        self.open.clear()
        if timed_out:
            self.ignore_before = now


#: sim s of a DTAP auction: AUCTION_BASE + AUCTION_STEP * k (k the auctioneer's tasks), at
#: most AUCTION_LONGEST (algorithms/dtap.py with the shipped parameters)
AUCTION_BASE, AUCTION_STEP, AUCTION_LONGEST = 1.0, 0.1, 3.0


class AuctionTrace:
    """Diagnostic: sim and wall s from each DTA task request to each bid on its vertex, and
    how late (sim s) a robot's next auction round followed the end of its last one."""

    def __init__(self):
        self.requests = {}          # vertex -> (sim, wall) time of its last request
        self.delays = []            # (sim s, wall s) per bid
        self.last_round = {}        # robot -> sim time of its last request
        self.lags = []              # sim s from an auction's end to the next round

    def note(self, data, sim, wall):
        if len(data) < 4:
            return
        if data[1] == MSG_SSI_TASK_REQUEST:
            self.requests[data[2]] = (sim, wall)
            prev = self.last_round.get(data[0])
            self.last_round[data[0]] = sim
            gap = None if prev is None else sim - prev - AUCTION_BASE
            if gap is not None and -1e-6 < gap < AUCTION_LONGEST - AUCTION_BASE + AUCTION_STEP:
                self.lags.append(round(gap % AUCTION_STEP, 6) % AUCTION_STEP)
        elif data[1] == MSG_SSI_BID and data[2] in self.requests:
            s, w = self.requests[data[2]]
            self.delays.append((sim - s, wall - w))

    def summary(self):
        """One line on the request-to-bid delays of the auctions traced."""
        if not self.delays:
            return "auction bids traced: none"
        d = sorted(x[0] for x in self.delays)
        w = sorted(x[1] for x in self.delays)
        n = len(d)
        return (f"auction bids traced: n {n}, request->bid sim s median {d[n // 2]:.3f} "
                f"p90 {d[int(0.9 * (n - 1))]:.3f} max {d[-1]:.3f}, over 0.5 s "
                f"{sum(x > 0.5 for x in d)}, over 1 s {sum(x > 1.0 for x in d)}, after the "
                f"clock moved {sum(x > 0 for x in d)}; wall ms median {1e3 * w[n // 2]:.1f} "
                f"p90 {1e3 * w[int(0.9 * (n - 1))]:.1f} max {1e3 * w[-1]:.1f}"
                + self.lag_summary())

    def lag_summary(self):
        """The next rounds' lags (their sim time after an auction's possible end, modulo
        AUCTION_STEP): what the holds cannot wait for, an agent's own timer."""
        if not self.lags:
            return ""
        g = sorted(self.lags)
        return (f"; next round after the auction's end (sim s, modulo {AUCTION_STEP:g}): n "
                f"{len(g)} median {g[len(g) // 2]:.3f} max {g[-1]:.3f}")


def reaction_deadline(robots, arrived_by, limit, counter, now):
    """The reaction hold at wall time ``now``: the wall time until which the clock waits, or
    None. ``robots`` have ``done_at`` (sim time of the last arrival without a new goal since,
    or None), ``hold_since`` (wall time the clock began to wait for it, or None) and
    ``released``; a robot that arrived by sim time ``arrived_by`` is waited for, at most
    ``limit`` wall s (then released until its next goal). ``counter`` (HoldCounter) counts
    the robots waited for and those released."""
    deadline = None
    for r in robots:
        if r.done_at is None or r.released or r.done_at > arrived_by:
            continue
        if r.hold_since is None:
            r.hold_since = now
            counter.holds += 1
        if now - r.hold_since >= limit:
            r.released = True
            counter.timeouts += 1
        else:
            end = r.hold_since + limit
            deadline = end if deadline is None else min(deadline, end)
    return deadline


class AuctionTimers:
    """The possible ends of the DTA auctions running (sim times): a task request by robot r at
    sim t may end at t + AUCTION_BASE + AUCTION_STEP * k, up to t + AUCTION_LONGEST (the
    length depends on r's task count, which the world does not know); r's next request
    replaces them. :meth:`reached` says when the clock has reached one, so that the world
    can hold the clock while the auctioneer's timer fires and it acts."""

    def __init__(self):
        self.ends = {}              # robot -> [sim times still ahead], ascending

    def note(self, data, sim):
        if len(data) >= 4 and data[0] >= 0 and data[1] == MSG_SSI_TASK_REQUEST:
            n = round((AUCTION_LONGEST - AUCTION_BASE) / AUCTION_STEP)
            self.ends[data[0]] = [sim + AUCTION_BASE + AUCTION_STEP * k for k in range(n + 1)]

    def reached(self, sim):
        """True if sim time ``sim`` reached a possible end not reached before."""
        hit = False
        for robot in list(self.ends):
            ends = self.ends[robot]
            while ends and ends[0] <= sim + 1e-9:
                ends.pop(0)
                hit = True
            if not ends:
                del self.ends[robot]
        return hit


#: wall s the clock waits at most, once every robot has announced itself ready, for the
#: monitor's GO (which it sends at once): the monitor's GO time is then the agents' GO time
GO_ANNOUNCE_WAIT = 2.0


class GoHold:
    """The GO hold (docs/abstract_world.md, "GO hold"): once all ``team`` robots have
    announced themselves ready (``[id, 10, 1]``) the clock stands still until GO
    (``[-1, 10, 100]``), at most ``announce_wait`` wall s, then ``go_wait`` wall s from the
    moment GO is seen. ``go_wait`` 0 turns it off. ``note`` takes every /results message with
    its wall time; ``until`` says till when the clock must stand still."""

    def __init__(self, team, go_wait, announce_wait=GO_ANNOUNCE_WAIT):
        if go_wait < 0 or announce_wait < 0:
            raise ValueError(f"~go_wait must be >= 0, got {go_wait}")
        self.team, self.go_wait, self.announce_wait = team, go_wait, announce_wait
        self.counter = HoldCounter()
        self.ready = set()
        self.go_seen = False
        self.awaiting_go = False    # every robot is ready: waiting for GO
        self.end = None             # wall time the hold ends (None: no hold pending)

    def note(self, now, data):
        """A /results message ``data`` at wall time ``now``; True if it is the first GO."""
        if self.go_seen or len(data) < 3 or data[1] != MSG_INIT:
            return False
        if data[0] == MONITOR_ID and data[2] == GO:
            self.go_seen, self.awaiting_go = True, False
            if self.go_wait > 0:
                self.end = now + self.go_wait
            return True
        if (data[2] == ROBOT_READY and 0 <= data[0] < self.team and self.go_wait > 0
                and not self.awaiting_go):
            self.ready.add(data[0])
            if len(self.ready) == self.team:
                self.awaiting_go = True
                self.end = now + self.announce_wait
        return False

    def until(self, now):
        """The wall time until which the clock stands still, or None (the hold is over: a
        hold that ended without GO counts as timed out, and no other wait for GO follows)."""
        if self.end is None:
            return None
        if now < self.end:
            return self.end
        self.end = None
        if self.awaiting_go:
            self.counter.timeouts += 1
        return None


class StartHold:
    """The start hold (docs/abstract_world.md, "Start hold"): the clock stands still at its
    first step until every one of the ``team`` robots has announced itself ready
    (``[id, 10, 1]``) or the monitor's GO (``[-1, 10, 100]``) is seen, at most ``wait`` wall
    s from :meth:`begin` (then it counts as timed out and the clock runs on). GO then comes
    at the same sim time in every run, however long the processes took to start. ``wait`` 0
    turns it off: agents that sleep on ROS time while they start (the original's) need it
    off. ``note`` takes every /results message; ``holding`` says whether the clock must
    still stand still."""

    def __init__(self, team, wait):
        if wait < 0:
            raise ValueError(f"~start_wait must be >= 0, got {wait}")
        self.team, self.wait = team, wait
        self.counter = HoldCounter()
        self.ready = set()
        self.end = None             # wall time the hold ends at the latest (None: not begun)
        self.over = wait == 0       # the hold has ended (or is off)

    def begin(self, now):
        """The clock has made its first step at wall time ``now``: the hold starts."""
        if not self.over and self.end is None:
            self.end = now + self.wait
            self.counter.holds += 1

    def note(self, data):
        """A /results message ``data``; ends the hold at the last ready or at GO."""
        if self.over or len(data) < 3 or data[1] != MSG_INIT:
            return
        if data[0] == MONITOR_ID and data[2] == GO:
            self.over = True
        elif data[2] == ROBOT_READY and 0 <= data[0] < self.team:
            self.ready.add(data[0])
            self.over = len(self.ready) == self.team

    def holding(self, now):
        """True while the clock must stand still at wall time ``now`` (the hold has begun
        and not ended); a hold that reaches its bound ends as timed out."""
        if self.over or self.end is None:
            return False
        if now >= self.end:
            self.over = True
            self.counter.timeouts += 1
            return False
        return True


class TimerReports:
    """The agents' reports (``/sim_timers`` per agent process;
    patrolling_sim.ros.sim_timers): ``[done, next]``, its timers due up to sim time ``done``
    have fired and ``next`` is its earliest pending deadline; ``[done, next, robot, t]``
    also says that robot ``robot`` has handled an event (GO, a goal's outcome) at sim time
    ``t``. :meth:`note` records a report (any thread, under the caller's lock); the
    stepping thread asks :meth:`waiting` whether the clock at sim time ``sim`` must stand
    still for a timer, and :meth:`has_handled` whether a robot's agent has handled its
    arrival. A process whose timer wait reached its bound is left out (:meth:`give_up`)
    until it reports again: an agent process that ended, or one too busy to answer, costs
    one bounded wait, not one per step."""

    def __init__(self):
        self.next = {}              # reporter -> earliest pending deadline (sim s)
        self.handled = {}           # robot -> latest sim time it reported an event handled
        self.counter = HoldCounter()

    def note(self, reporter, done, nxt, robot=None, at=None):
        """A report of ``reporter`` (any hashable): its timers due up to sim time ``done``
        have fired; ``nxt`` is its earliest pending deadline (< 0: none); ``robot``, if
        given, has handled an event at sim time ``at``."""
        if nxt < 0:
            self.next.pop(reporter, None)
        else:
            self.next[reporter] = nxt
        if robot is not None:
            self.handled[robot] = max(self.handled.get(robot, at), at)

    def waiting(self, sim):
        """The reporters with a deadline at or before ``sim`` that has not fired yet (sorted
        by deadline); empty if the clock may move on."""
        due = [(d, r) for r, d in self.next.items() if d <= sim + DEADLINE_TOLERANCE]
        return [r for _, r in sorted(due, key=lambda x: (x[0], str(x[1])))]

    def give_up(self, reporters):
        """Leave ``reporters`` out until their next report (their wait timed out)."""
        for r in reporters:
            self.next.pop(r, None)

    def reports(self, robot):
        """True if ``robot``'s agent reports the events it handled (it reported one)."""
        return robot in self.handled

    def has_handled(self, robot, sim):
        """True if ``robot``'s agent reported an event handled at sim time ``sim`` or later
        (or it does not report: nothing to wait for)."""
        at = self.handled.get(robot)
        return at is None or at >= sim - DEADLINE_TOLERANCE
