"""The abstract world's clock holds (docs/abstract_world.md): when the stepping loop keeps its
clock still for the agents, as a mixin of the world node (``abstract_world.WorldNode``). The
rules themselves are pure functions and classes in ``clock_hold.py``; this module holds their
parameters and the waits, which need the node's lock, condition, robots and world."""
import time

from straight_line_world import EPS
from clock_hold import (AuctionTimers, GoHold, HoldCounter, MessageHold, StartHold,
                        TimerReports, reaction_deadline)
from patrolling_sim.ros.sim_timers import READER_PARAM, REPORT_TOPIC

#: sim s from an arrival (plus /goal_reached_wait) to the next departure at the earliest, and
#: then the clock waits for the goal: the reference runs' median turnaround (4 steps of 20 ms)
REACTION_TIME = 0.08
#: wall s the clock waits at most per arrival (then the agent is taken to wait on purpose)
REACTION_WAIT = 0.2
#: wall s of quiet after a message or goal before the clock moves on (delivery takes < 1 ms)
MESSAGE_QUIET = 0.005
#: wall s of quiet after a DTA task request, unless every teammate bid (x30 quiet: bids came
#: within 3 ms in 9 of 10 cases, 20 ms at most)
ANSWER_QUIET = 0.02
#: wall s the clock waits at most per message hold (then it runs on and counts a time-out)
MESSAGE_WAIT = 0.1
#: wall s the clock stands still once GO is seen, so that every agent reads GO at GO's sim time
#: (each starts its start delay then); GO asks for no answer, so no silence can end it earlier
GO_WAIT = 0.5
#: wall s the clock waits at most for an agent process's timers due at a step to fire (its
#: ``/sim_timers`` report); then the process is left out until it reports again
TIMER_WAIT = 0.5
#: wall s the clock waits at most for an agent's report that it handled its robot's arrival
ARRIVAL_WAIT = 1.0
#: wall s between two publications of the clock and the action servers' status while the
#: start hold lasts (a node that starts meanwhile reads both within this time)
START_REPUBLISH = 0.1


class WorldHolds:
    """The clock holds of a world node that has ``rospy``, ``lock``, ``traffic`` (a condition
    on ``lock``), ``world`` (StraightLineWorld) and ``robots`` (RobotServer list)."""

    def _init_holds(self, rospy, team):
        """Read the holds' parameters (raises ValueError for a bad one) and make their
        state, for a team of ``team`` robots."""
        gwait = float(rospy.get_param("/goal_reached_wait", 0.0))
        self.hold_after = gwait + float(rospy.get_param("~reaction_time", REACTION_TIME))
        self.hold_limit = float(rospy.get_param("~reaction_wait", REACTION_WAIT))
        self.reaction = HoldCounter()
        self.arrival = HoldCounter()        # waits for an agent's report on its arrival
        if self.hold_after < 0 or self.hold_limit < 0:
            raise ValueError("~reaction_time and ~reaction_wait must be >= 0")
        self.message_hold = MessageHold(float(rospy.get_param("~message_quiet", MESSAGE_QUIET)),
                                        float(rospy.get_param("~answer_quiet", ANSWER_QUIET)),
                                        float(rospy.get_param("~message_wait", MESSAGE_WAIT)),
                                        team)
        # hold the clock (as after a message) where a DTA auction may end: the auctioneer's
        # timer fires there and it acts (a new round, a goal)
        self.timers = AuctionTimers() if rospy.get_param("~auction_timers", True) else None
        self.go_hold = GoHold(team, float(rospy.get_param("~go_wait", GO_WAIT)))
        # off unless asked: the original's agents sleep on ROS time while they start
        self.start_hold = StartHold(team, float(rospy.get_param("~start_wait", 0.0)))
        # hold the clock at a step where an agent process has a timer due until it reports
        # that the timer fired (patrolling_sim.ros.sim_timers; the original's agents do not
        # report, and the auction-timer rule above stands in for theirs)
        self.timer_wait = float(rospy.get_param("~timer_wait", TIMER_WAIT))
        if self.timer_wait < 0:
            raise ValueError(f"~timer_wait must be >= 0, got {self.timer_wait}")
        self.timer_reports = TimerReports() if self.timer_wait > 0 else None
        self.arrival_wait = float(rospy.get_param("~arrival_wait", ARRIVAL_WAIT))
        if self.arrival_wait < 0:
            raise ValueError(f"~arrival_wait must be >= 0, got {self.arrival_wait}")

    def _subscribe_reports(self, rospy):
        """Read the agents' reports (REPORT_TOPIC) if the timer hold is on, and tell the
        agents so (READER_PARAM: they wait for this subscription before they announce
        themselves, so no report is lost)."""
        if self.timer_reports is None:
            return
        from std_msgs.msg import Float64MultiArray
        self.timers_sub = rospy.Subscriber(REPORT_TOPIC, Float64MultiArray,
                                           self._on_timer_report, queue_size=100)
        rospy.set_param(READER_PARAM, True)

    def _on_timer_report(self, msg):
        """``[done, next]`` from an agent process's timer scheduler: recorded per sender,
        and traffic (the timers' own messages went out before the report)."""
        if len(msg.data) < 2:
            return
        sender = getattr(msg, "_connection_header", {}).get("callerid", "?")
        robot = int(msg.data[2]) if len(msg.data) >= 4 else None
        with self.lock:
            # an event handled counts at the world's time of the report (the clock stands
            # still while the world waits for it; the agent's own reading may lag a step)
            self.timer_reports.note(sender, msg.data[0], msg.data[1], robot, self.world.time)
            self.message_hold.note(time.monotonic())
            self.traffic.notify_all()

    def _hold_at_start(self, republish):
        """Stop the clock while the start hold lasts (clock_hold.StartHold), calling
        ``republish()`` (the clock and the action servers' status, which the agents need to
        find their move_base) every START_REPUBLISH wall s; True if it held."""
        hold = self.start_hold
        if hold.over:
            return False
        start = last = time.monotonic()
        hold.begin(start)
        while not self.rospy.is_shutdown():
            with self.lock:
                if not hold.holding(time.monotonic()):
                    break
                self.traffic.wait(max(0.0, last + START_REPUBLISH - time.monotonic()))
            if time.monotonic() - last >= START_REPUBLISH:
                last = time.monotonic()
                republish()
        hold.counter.wall += time.monotonic() - start
        return True

    def _hold_for_go(self):
        """Stop the clock while the GO hold lasts (clock_hold.GoHold); True if it held."""
        with self.lock:
            start = time.monotonic()
            if self.go_hold.until(start) is None:
                return False
            self.go_hold.counter.holds += 1
            while not self.rospy.is_shutdown():
                end = self.go_hold.until(time.monotonic())
                if end is None:
                    break
                self.traffic.wait(end - time.monotonic())
            self.go_hold.counter.wall += time.monotonic() - start
        return True

    def _hold_for_timers(self):
        """Stop the clock (just published) while an agent process has a timer due at this
        step that has not fired (clock_hold.TimerReports), at most ``timer_wait`` wall s;
        returns True if it held."""
        reports = self.timer_reports
        start = time.monotonic()
        held = False
        with self.lock:
            while not self.rospy.is_shutdown():
                waiting = reports.waiting(self.world.time)
                if not waiting:
                    break
                if not held:
                    held = True
                    reports.counter.holds += 1
                left = start + self.timer_wait - time.monotonic()
                if left <= 0:
                    reports.counter.timeouts += 1
                    reports.give_up(waiting)
                    break
                self.traffic.wait(left)
        if held:
            reports.counter.wall += time.monotonic() - start
        return held

    def _hold_for_reactions(self):
        """Stop the clock while a robot that arrived ``hold_after`` sim s ago has no new goal
        yet, for at most ``hold_limit`` wall s per arrival (after that the robot is taken to
        be waiting on purpose: an auction, an algorithm's pause). Returns True if it held."""
        start = None
        with self.lock:
            while not self.rospy.is_shutdown():
                now = time.monotonic()
                deadline = reaction_deadline(self.robots, self.world.time - self.hold_after + EPS,
                                             self.hold_limit, self.reaction, now)
                if deadline is None:
                    break
                start = now if start is None else start
                self.traffic.wait(max(0.0, deadline - now))
        if start is not None:
            self.reaction.wall += time.monotonic() - start
        return start is not None

    def _announce_arrivals(self, arrived, handles):
        """SUCCEEDED to the robots that arrived in this step, one at a time in id order; an
        arrival is traffic (the message hold follows it). Before the next robot's, the clock
        (still at this step) waits until this one has its next goal (at most
        ``hold_limit`` wall s) and the traffic is quiet, so that robots arriving together are
        handled in the same order at any pace, each knowing what the previous one sent.
        First the clock of this step gets ``message_quiet`` wall s to reach the agents (it
        travels on another connection than the action's result), so that they read this
        step's time when they decide."""
        if self.message_hold.enabled:
            time.sleep(self.message_hold.quiet)
        for k, (i, gh) in enumerate(zip(arrived, handles)):
            if gh is not None:
                gh.set_succeeded()
            with self.lock:
                self.message_hold.note(time.monotonic())
                reports = self.timer_reports is not None and self.timer_reports.reports(i)
            if reports and gh is not None:
                self._wait_for_handled(i)
                self._hold_for_messages()
            elif k + 1 < len(arrived) and self.message_hold.enabled:
                self._wait_for_goal(self.robots[i])
                self._hold_for_messages()

    def _wait_for_handled(self, i):
        """Wait (at most ``arrival_wait`` wall s, an arrival hold) until robot ``i``'s agent
        reports that it handled its arrival at this step (``/sim_timers``): everything it
        does for the arrival then happens at this step's time, at any pace and load."""
        if self.arrival_wait <= 0:
            return
        start = time.monotonic()
        c = self.arrival
        with self.lock:
            c.holds += 1
            while not self.rospy.is_shutdown():
                handled = self.timer_reports.has_handled(i, self.world.time)
                left = start + self.arrival_wait - time.monotonic()
                if handled or left <= 0:
                    c.timeouts += not handled
                    break
                self.traffic.wait(left)
        c.wall += time.monotonic() - start

    def _wait_for_goal(self, r):
        """Wait (at most ``hold_limit`` wall s, a reaction hold) until robot ``r`` has a
        goal again."""
        start = time.monotonic()
        with self.lock:
            if r.done_at is None or self.hold_limit <= 0:
                return
            self.reaction.holds += 1
            while r.done_at is not None and not self.rospy.is_shutdown():
                left = start + self.hold_limit - time.monotonic()
                if left <= 0:
                    self.reaction.timeouts += 1
                    break
                self.traffic.wait(left)
        self.reaction.wall += time.monotonic() - start

    def _hold_for_messages(self):
        """Stop the clock while the agents' traffic is not quiet yet (clock_hold.MessageHold);
        returns True if it held."""
        if not self.message_hold.enabled:
            return False
        held = False
        with self.lock:
            while not self.rospy.is_shutdown():
                now = time.monotonic()
                until = self.message_hold.wait_until(now)
                if until is None:
                    return held
                held = True
                self.traffic.wait(max(0.0, until - now))
        return held

    def _hold_counters(self):
        c = {"go": self.go_hold.counter, "reaction": self.reaction,
             "message": self.message_hold.counter}
        if self.start_hold.wait > 0:
            c["start"] = self.start_hold.counter
        if self.timer_reports is not None:
            c["timer"] = self.timer_reports.counter
            c["arrival"] = self.arrival
        return c
