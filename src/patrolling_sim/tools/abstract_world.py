#!/usr/bin/python3
"""The abstract world: one node standing in for the simulator and every robot's move_base,
with straight-line motion and nothing else (docs/abstract_world.md).

It is the world the original's reference runs were made in, so that our agents and monitor
can be compared with the original's on equal terms, and a cheap world for ROS-level tests:

- ``/clock`` in fixed steps of ``~step`` sim seconds (0.02), paced at ``~speedup`` x real
  time after the monitor's GO (0: not paced, each step as soon as the clock holds allow) and
  ``~speedup_before_go`` x before it; when the machine cannot keep up, sim time slows down
  uniformly (steps are never skipped or merged), so sim-time results do not depend on the
  machine's load;
- per robot ``robot_i/move_base`` (move_base_msgs/MoveBase action): on a goal the robot
  moves in a straight line from its CURRENT position to the goal at ``~speed`` m/s, no
  acceleration, no turning, no obstacles, robots pass through each other; the goal
  SUCCEEDS at the first step at or after arrival; a cancel stops the robot where it is and
  PREEMPTS the goal; a new goal preempts the previous one;
- per robot ``robot_i/move_base/clear_costmaps`` (std_srvs/Empty, does nothing);
- per robot ``robot_i/odom`` (nav_msgs/Odometry, frame ``robot_i/odom``, child
  ``robot_i/base_link``) every ``~odom_period`` sim s, and with ``~publish_tf`` the same
  transforms on /tf plus identity ``map -> robot_i/odom`` on /tf_static;
- with ``~feedback`` true, move_base feedback (``base_position`` in ``map``) with each
  odometry message; the reference world sent none, so the agents never published
  /positions and never detected interference;
- a robot leaves ``/goal_reached_wait`` + ``~reaction_time`` sim s after an arrival at the
  earliest; then the clock waits for its goal (at most ``~reaction_wait`` wall s); after
  an arrival, a goal or a ``/results`` message the clock waits until the traffic is quiet
  (at most ``~message_wait`` wall s per hold; ``clock_hold.py``): pace and load cost no
  sim time;
- ``~status`` (std_msgs/String, JSON) about twice a wall second: sim time, achieved pace
  (``rtf``), GO seen, goals / successes / preemptions per robot, the clock holds.

Start positions from ``/initial_pos`` (flat x0,y0,x1,y1,...), the team size ``~team_size``
(default: all). At shutdown the node logs goals per robot, the clock holds and the sim time
between a SUCCEEDED and the robot's next goal (the agents' turnaround).

Private parameters: ~team_size (int), ~speed (1.0 m/s), ~step (0.02 s), ~speedup (20; 0:
not paced), ~speedup_before_go (2, at most ~speedup), ~odom_period (0.1 s), ~feedback (false),
~publish_tf (true), ~reaction_time (0.08 s), ~reaction_wait (0.2 wall s; 0 = never hold),
~message_quiet (0.005 wall s), ~answer_quiet (0.02 wall s), ~message_wait (0.1 wall s; 0 off),
~auction_timers (true: hold where a DTA auction may end), ~timer_wait (0.5 wall s the clock
waits at most at a step where an agent process reported a timer due; 0 off), ~arrival_wait
(1.0 wall s the clock waits at most for an agent's report that it handled an arrival; 0
off), ~go_wait (0.5 wall s the clock stands still after GO, and from the last robot's ready
announcement until GO; 0 off), ~start_wait (wall s the clock stands still at its first step
until every robot has announced itself ready, so that GO comes at the same sim time in every
run; 0, the default, off: agents that sleep on ROS time while they start, as the original's,
need it off; the runner sets 120 for its own agents).

Diagnostic: with ``PATROLLING_SIM_TRACE_AUCTIONS=1`` in its environment the node logs at
shutdown the sim and wall s from each DTA task request (type 41) to each bid (type 42).
"""
import json
import math
import os
import statistics
import sys
import threading
import time

# the motion model lives beside this script (Python puts the script folder on sys.path)
from straight_line_world import StraightLineWorld, read_positions
from clock_hold import AuctionTrace, totals
from robot_server import RobotServer
from world_holds import WorldHolds

STATUS_PERIOD = 0.2        # sim s between action status messages (actionlib's 5 Hz)


class WorldNode(WorldHolds):
    """The world's ROS node: clock, motion, action servers, odometry; its clock holds are
    :class:`world_holds.WorldHolds`."""

    def __init__(self):
        import rospy
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import Int16MultiArray, String
        self.rospy = rospy
        positions = read_positions(rospy.get_param("/initial_pos", None),
                                   rospy.get_param("~team_size", None))
        self.world = StraightLineWorld(positions, float(rospy.get_param("~speed", 1.0)),
                                       float(rospy.get_param("~step", 0.02)))
        self.speedup = float(rospy.get_param("~speedup", 20.0))
        if not self.speedup >= 0:
            raise ValueError(f"~speedup must be >= 0, got {self.speedup}")
        self.speedup = self.speedup or math.inf     # 0: each step as soon as the holds allow
        self.speedup_before_go = min(float(rospy.get_param("~speedup_before_go", 2.0)),
                                     self.speedup)
        if not self.speedup_before_go > 0:
            raise ValueError(f"~speedup_before_go must be > 0, got {self.speedup_before_go}")
        odom_period = float(rospy.get_param("~odom_period", 0.1))
        if not odom_period > 0:
            raise ValueError(f"~odom_period must be > 0, got {odom_period}")
        self.odom_every = max(1, round(odom_period / self.world.step_length))
        self.feedback = bool(rospy.get_param("~feedback", False))
        self.publish_tf = bool(rospy.get_param("~publish_tf", True))
        self.lock = threading.Lock()
        self.traffic = threading.Condition(self.lock)       # a goal or a message came
        self._init_holds(rospy, len(positions))
        self.go_at = None
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=1)
        self.clock = Clock()
        self.status_pub = rospy.Publisher("~status", String, queue_size=1)
        self.robots = [RobotServer(self, i) for i in range(len(positions))]
        if self.publish_tf:
            from tf2_msgs.msg import TFMessage
            self.tf_pub = rospy.Publisher("/tf", TFMessage, queue_size=1)
            self.tf_msg = TFMessage()
            self._static_tf(TFMessage)
        self.trace = (AuctionTrace() if os.environ.get("PATROLLING_SIM_TRACE_AUCTIONS") == "1"
                      else None)
        self.results_sub = rospy.Subscriber("/results", Int16MultiArray, self._on_results,
                                            queue_size=100)
        self._subscribe_reports(rospy)
        for r in self.robots:
            r.server.start()
            # the action server's own 5 Hz status timer is a thread woken by every clock
            # step; the stepping loop publishes the status at the same sim-time rate instead
            timer = getattr(r.server, "status_timer", None)
            if timer is not None:
                timer.shutdown()
        self.status_every = max(1, round(STATUS_PERIOD / self.world.step_length))
        rospy.loginfo("abstract_world: %d robots, %.2f m/s, step %.3f s, x%g (x%g before GO), "
                      "feedback %s", len(self.robots), self.world.speed, self.world.step_length,
                      self.speedup, self.speedup_before_go, self.feedback)

    def _static_tf(self, TFMessage):
        from geometry_msgs.msg import TransformStamped
        static = TFMessage()
        for r in self.robots:
            t = TransformStamped()
            t.header.frame_id = "map"
            t.child_frame_id = f"robot_{r.i}/odom"
            t.transform.rotation.w = 1.0
            static.transforms.append(t)
            d = TransformStamped()
            d.header.frame_id = r.odom.header.frame_id
            d.child_frame_id = r.odom.child_frame_id
            self.tf_msg.transforms.append(d)
        self.static_pub = self.rospy.Publisher("/tf_static", TFMessage, queue_size=1,
                                               latch=True)
        self.static_pub.publish(static)

    def _on_results(self, msg):
        d = msg.data
        now = time.monotonic()
        go = False
        if len(d) >= 2:                             # any message: the agents react to GO too
            with self.lock:
                self.message_hold.note(now, d)
                self.start_hold.note(d)
                if self.timers is not None:
                    self.timers.note(d, self.world.time)
                if self.go_hold.note(now, d):
                    go, self.go_at = True, self.world.time
                self.traffic.notify_all()
        if self.trace is not None:
            self.trace.note(d, self.world.time, now)
        if go:
            self.rospy.loginfo("abstract_world: GO at sim %.2f s", self.go_at)

    def run(self):
        """Step until shutdown; the summary is logged however the loop ends."""
        try:
            self._step_loop()
        except self.rospy.ROSException:
            if not self.rospy.is_shutdown():      # publishing while shutting down is fine
                raise
        finally:
            self.log_summary()

    def _step_loop(self):
        rospy = self.rospy
        # this node owns the clock: it sets its own ROS time directly instead of reading
        # back every /clock message it publishes (rospy subscribed to /clock at init_node)
        from rospy.impl import simtime
        own_sub = getattr(simtime, "_clock_sub", None)
        if own_sub is not None:
            own_sub.unregister()
        step = self.world.step_length
        next_wall = time.monotonic()
        window = (time.monotonic(), 0.0)
        last_status = 0.0
        rtf = 0.0
        while not rospy.is_shutdown():
            held = self.world.steps > 0 and self._hold_at_start(self._republish)
            held = self._hold_for_go() or held
            held = self.hold_limit > 0 and self._hold_for_reactions() or held
            if self._hold_for_messages() or held:
                next_wall = time.monotonic()       # the clock stood still: no catch-up
            with self.lock:
                arrived = self.world.advance()
                t = rospy.Time.from_sec(self.world.time)
                handles = []
                for i in arrived:
                    r = self.robots[i]
                    handles.append(r.gh)
                    r.gh = None
                    r.succeeded += 1
                    r.done_at = self.world.time
            rospy.rostime._set_rostime(t)
            self.clock.clock = t
            self.clock_pub.publish(self.clock)
            if self.timer_reports is not None and self._hold_for_timers():
                self._hold_for_messages()      # their actions' messages, before arrivals
            if self.timers is not None:
                with self.lock:
                    if self.timers.reached(self.world.time):
                        self.message_hold.note(time.monotonic())
            if arrived:
                self._announce_arrivals(arrived, handles)
            if self.world.steps % self.odom_every == 0:
                self._publish_odometry(t)
            if self.world.steps % self.status_every == 0:
                for r in self.robots:
                    r.server.publish_status()
            if (self.go_at is not None and self.results_sub is not None
                    and self.trace is None and not self.message_hold.enabled):
                self.results_sub.unregister()     # GO seen: no need to read every visit
                self.results_sub = None
            pace = self.speedup if self.go_at is not None else self.speedup_before_go
            next_wall += step / pace
            now = time.monotonic()
            if next_wall > now:
                time.sleep(next_wall - now)
            elif now - next_wall > 0.1:
                next_wall = now        # lagging: slow down, never catch up in a burst
            if now - last_status >= 0.5:
                w0, s0 = window
                if now > w0:
                    rtf = (self.world.time - s0) / (now - w0)
                window = (now, self.world.time)
                last_status = now
                self.status_pub.publish(json.dumps(self.status(rtf)))

    def _republish(self):
        """The clock and the action servers' status again, the clock standing still."""
        self.clock_pub.publish(self.clock)
        for r in self.robots:
            r.server.publish_status()

    def _publish_odometry(self, stamp):
        from move_base_msgs.msg import MoveBaseFeedback
        with self.lock:
            msgs = [(r, r.fill_odom(stamp, self.world), r.gh) for r in self.robots]
        for r, odom, gh in msgs:
            r.odom_pub.publish(odom)
            if self.feedback and gh is not None:
                fb = MoveBaseFeedback()
                fb.base_position.header.frame_id = "map"
                fb.base_position.header.stamp = stamp
                fb.base_position.pose = odom.pose.pose
                gh.publish_feedback(fb)
        if self.publish_tf:
            for (r, odom, _), tr in zip(msgs, self.tf_msg.transforms):
                tr.header.stamp = stamp
                tr.transform.translation.x = odom.pose.pose.position.x
                tr.transform.translation.y = odom.pose.pose.position.y
                tr.transform.rotation = odom.pose.pose.orientation
            self.tf_pub.publish(self.tf_msg)

    def status(self, rtf):
        return dict(sim_time=round(self.world.time, 3), rtf=round(rtf, 3),
                    go=self.go_at is not None, go_at=self.go_at,
                    goals=[r.goals for r in self.robots],
                    succeeded=[r.succeeded for r in self.robots],
                    preempted=[r.preempted for r in self.robots],
                    **totals(self._hold_counters()))

    def log_summary(self):
        if self.trace is not None:
            print("abstract_world: " + self.trace.summary(), flush=True)
        turn = [x for r in self.robots for x in r.turnaround]
        s = self.status(0.0)
        line = (f"abstract_world: end at sim {s['sim_time']:.2f} s, GO at {s['go_at']}; goals "
                f"{s['goals']} succeeded {s['succeeded']} preempted {s['preempted']}; clock "
                f"held for a reaction {self.reaction.holds} times, {self.reaction.timeouts} of "
                f"them given up after {self.hold_limit:g} wall s, {self.reaction.wall:.2f} wall "
                f"s in all; for messages {self.message_hold.counter.holds} times, "
                f"{self.message_hold.counter.timeouts} timed out after "
                f"{self.message_hold.limit:g} wall s, {self.message_hold.counter.wall:.2f} wall "
                f"s in all; for GO {self.go_hold.counter.wall:.2f} wall s")
        if self.start_hold.wait > 0:
            c = self.start_hold.counter
            line += (f"; at the start {c.wall:.2f} wall s"
                     + (f", timed out after {self.start_hold.wait:g} wall s" if c.timeouts
                        else ""))
        if self.timer_reports is not None:
            c = self.timer_reports.counter
            line += (f"; for the agents' timers {c.holds} times, {c.timeouts} timed out after "
                     f"{self.timer_wait:g} wall s, {c.wall:.2f} wall s in all; for arrivals "
                     f"{self.arrival.holds} times, {self.arrival.timeouts} timed out after "
                     f"{self.arrival_wait:g} wall s, {self.arrival.wall:.2f} wall s in all")
        if turn:
            line += (f"; turnaround SUCCEEDED->next goal (sim s): n {len(turn)} mean "
                     f"{statistics.mean(turn):.3f} median {statistics.median(turn):.3f} "
                     f"max {max(turn):.3f}")
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


def main():
    from spqrel_nav_lite.ros_util import init_node_signal_safe
    # SIGINT/SIGTERM handled outside the main thread, which publishes /clock at every step
    # (rospy's own handler could deadlock there, see init_node_signal_safe)
    init_node_signal_safe("abstract_world")
    try:
        node = WorldNode()
    except (ValueError, KeyError) as e:
        sys.stderr.write(f"abstract_world: error: {e}\n")
        return 2
    node.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
