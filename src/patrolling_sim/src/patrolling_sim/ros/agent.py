"""The PatrolAgent node: ROS glue around :class:`patrolling_sim.agent.core.PatrolAgentCore`,
the one implementation of a robot's life cycle (see ``docs/protocol.md``).

This module only connects the core to ROS: the ``robot_i/move_base`` action client (goals,
feedback, outcomes), ``/results`` and ``/positions``, one-shot timers on ROS time (``sim_timers``),
the back-up twists on ``robot_i/cmd_vel`` and the ``clear_costmaps`` service. Every callback
takes ``self.lock`` and hands the event to the core; nothing blocks inside a callback. A
goal's outcome is the exception: actionlib reports it holding the goal's own mutex, so it is
handed to the node's outcome thread, which takes ``self.lock`` (see :meth:`_on_transition`).
Start-up: load the graph, read ``/initial_pos`` (start vertex = nearest vertex, ``|dx|+|dy|``),
wait for ``robot_i/move_base`` (logging every 5 s), then the core announces and waits for GO.
"""
import queue
import re
import threading

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import Odometry
from std_msgs.msg import Int16MultiArray
from std_srvs.srv import Empty

from patrolling_sim import algorithms
from patrolling_sim.common import paths
from patrolling_sim.agent.core import Effects
from patrolling_sim.agent.factory import build_agent
from patrolling_sim.algorithms.base import MSG_FAILURE
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.protocol import GO, MONITOR_ID, MSG_INIT
from patrolling_sim.model.graph import PatrolGraph, load_graph
from patrolling_sim.ros import sim_timers
from patrolling_sim.ros.agent_scenario import AgentScenario
from patrolling_sim.ros.agent_params import (AgentError, clamp_int16, float_param, parse_ids,
                                             parse_robot_frame, read_common_params,
                                             start_vertex_from)
import sys

SERVER_LOG_PERIOD = 5.0        # s between "waiting for move_base" log lines


class PatrolAgent(Effects):
    """One robot. Construct inside an initialised rospy node, then :meth:`run`."""

    def __init__(self, map_arg, robot_id, algorithm, team_size=None, seed=None, params=None):
        self.id = int(robot_id)
        if self.id < 0:
            raise AgentError(f"robot id must be >= 0, got {robot_id}")
        self.alg = algorithm
        try:
            _, graph_path = paths.map_files(map_arg)
            self.graph = PatrolGraph(load_graph(graph_path))
        except PatrolInputError as e:
            raise AgentError(str(e))
        self.map_name = paths.map_name(map_arg)
        self.graph.name = self.map_name
        rospy.loginfo("Loaded graph %s with %d nodes and %d edges", self.map_name, self.graph.n,
                      sum(1 for u, w in self.graph.G.edges() if u < w))

        if not rospy.has_param("/initial_pos"):
            raise AgentError("/initial_pos is not set (start positions x0,y0,x1,y1,...)", 1)
        initial_pos = rospy.get_param("/initial_pos")
        if isinstance(initial_pos, str):
            initial_pos = [t for t in re.split(r"[\s,\[\]]+", initial_pos) if t]
        self.start_vertex, self.start_xy = start_vertex_from(self.graph, initial_pos, self.id)
        if team_size is None:
            team_size = max(len(initial_pos) // 2, self.id + 1)
        self.team_size = int(team_size)
        if self.team_size < 1 or self.id >= self.team_size:
            raise AgentError(f"robot id {self.id} is outside a team of {self.team_size}")

        goal_wait = float_param("/goal_reached_wait", 0.0, minimum=0.0)
        comm_delay = float_param("/communication_delay", 0.0, minimum=0.0)
        loss = float_param("/lost_message_rate", 0.0, minimum=0.0)
        if loss > 1.0:
            raise AgentError(f"/lost_message_rate must be in [0, 1], got {loss}")
        if algorithm not in algorithms.REGISTRY:
            raise AgentError(f"~algorithm: unknown algorithm '{algorithm}' (known: "
                             f"{', '.join(algorithms.names()) or 'none'})")

        self.lock = threading.RLock()
        self.gh = None                 # ClientGoalHandle of the active goal
        self._start_outcome_thread()
        self.timers = set()
        self.clamp_warned = False
        self.announce_timer = None
        self.scenario = AgentScenario(map_arg, self.id, self.team_size, initial_pos)
        try:
            self.core = build_agent(self, self.graph, self.id, self.team_size, self.map_name,
                                    algorithm, self.start_vertex, self.start_xy,
                                    seed=self.id if seed is None else int(seed),
                                    params=params, goal_wait=goal_wait,
                                    comm_delay=comm_delay, loss=loss,
                                    **self.scenario.core_kwargs())
        except PatrolInputError as e:
            raise AgentError(str(e))
        self.strategy = self.core.strategy
        self.scenario.attach(self)

        ns = f"robot_{self.id}"
        self.results_pub = rospy.Publisher("/results", Int16MultiArray, queue_size=100)
        self.positions_pub = rospy.Publisher("/positions", Odometry, queue_size=1)
        self.cmd_pub = rospy.Publisher(f"{ns}/cmd_vel", Twist, queue_size=1)
        self.clear_name = f"{ns}/move_base/clear_costmaps"
        self.server_name = rospy.resolve_name(f"{ns}/move_base")
        self.client = actionlib.ActionClient(self.server_name, MoveBaseAction)
        self.frame_tag = f"robot_{self.id}/map"
        sim_timers.scheduler()    # made now: its report topic is connected before GO
        sim_timers.delivery.add_agent(self.id)
        rospy.Subscriber("/results", Int16MultiArray, self._on_results, queue_size=100)
        rospy.Subscriber("/positions", Odometry, self._on_positions, queue_size=10)

    # -- Effects: what the core asks of ROS -------------------------------------------------
    def now(self):
        return rospy.get_time()

    def log(self, text):
        rospy.loginfo("%s", text)

    def end(self):
        rospy.signal_shutdown("monitor END")

    def call_later(self, delay, fn):
        """Run ``fn()`` (under the lock) ``delay`` s of ROS time after now, without blocking:
        the deadline is fixed now, whenever the process's timer thread gets to run
        (:mod:`patrolling_sim.ros.sim_timers`)."""
        holder = {}

        def fire():
            with self.lock:
                self.timers.discard(holder.get("t"))
                if rospy.core.is_shutdown_requested():
                    return
                try:
                    fn()
                except Exception as e:  # a failing callback must not kill the node silently
                    rospy.logerr("robot %d: error in timed callback: %s", self.id, e)
                    raise

        with self.lock:           # held until holder is filled: fire() waits for it
            t = sim_timers.call_later(delay, fire)
            holder["t"] = t
            self.timers.add(t)
        return t

    def publish(self, data):
        if not self.scenario.may_publish() and (len(data) < 2 or data[1] != MSG_FAILURE):
            return                      # a failed robot is silent (its pending timers too)
        data, clamped = clamp_int16(data)
        sim_timers.delivery.sent()
        if clamped and not self.clamp_warned:
            self.clamp_warned = True
            rospy.logwarn("robot %d: /results payload clamped to int16 (type %s)", self.id,
                          data[1] if len(data) > 1 else "?")
        publish_unless_stopping(self.results_pub, Int16MultiArray(data=data))

    def send_goal(self, vertex, seq):
        """A move_base goal to ``vertex`` (replaces the active goal: a self-cancel)."""
        self.cancel_goal()
        goal = MoveBaseGoal()
        goal.target_pose.header.frame_id = "map"
        goal.target_pose.header.stamp = rospy.Time.now()
        x, y = self.graph.pos[vertex]
        goal.target_pose.pose.position.x = float(x)
        goal.target_pose.pose.position.y = float(y)
        goal.target_pose.pose.orientation.w = 1.0
        self.gh = self.client.send_goal(
            goal, transition_cb=lambda gh: self._on_transition(gh, seq),
            feedback_cb=lambda gh, fb: self._on_feedback(fb, seq))

    def stop_base(self):
        """A zero twist now and 0.5 s later: the base stays where it is (after a failure)."""
        self.cmd_pub.publish(Twist())
        self.call_later(0.5, lambda: self.cmd_pub.publish(Twist()))

    def cancel_goal(self):
        gh, self.gh = self.gh, None
        if gh is not None:
            try:
                gh.cancel()
            except Exception as e:
                rospy.logdebug("robot %d: cancel failed: %s", self.id, e)

    def clear_costmaps(self):
        """Call robot_i/move_base/clear_costmaps if it exists, in a background thread."""
        def work():
            try:
                rospy.wait_for_service(self.clear_name, timeout=1.0)
                rospy.ServiceProxy(self.clear_name, Empty)()
            except (rospy.ROSException, rospy.ServiceException):
                rospy.logdebug("robot %d: no %s", self.id, self.clear_name)
        threading.Thread(target=work, daemon=True).start()

    def backup(self):
        """Reverse at 0.1 m/s, after 0.2 s rotate at 0.5 rad/s, stop after about 1 s."""
        def twist(lin, ang):
            t = Twist()
            t.linear.x = lin
            t.angular.z = ang
            return t
        self.cmd_pub.publish(twist(-0.1, 0.0))
        self.call_later(0.2, lambda: self.cmd_pub.publish(twist(0.0, 0.5)))
        self.call_later(0.95, lambda: self.cmd_pub.publish(twist(0.0, 0.0)))

    # -- start-up ------------------------------------------------------------------------
    def wait_for_server(self):
        while not rospy.is_shutdown() and self.core.phase != "ended":
            if self.client.wait_for_server(rospy.Duration(SERVER_LOG_PERIOD)):
                return True
            rospy.loginfo("robot %d: waiting for the %s action server...", self.id,
                          self.server_name)
        return False

    def run(self):
        """Life cycle of a single-agent node: :meth:`start`, spin until END or shutdown."""
        if self.start():
            rospy.spin()
        self.shutdown()
        return 0

    def start(self):
        """Wait for ``robot_i/move_base``, then let the core announce until GO (callbacks do
        the rest). Returns False if the node shut down meanwhile."""
        if self.id == 0 or not rospy.has_param("/algorithm_params"):
            rospy.set_param("/algorithm_params", str(self.strategy.algorithm_params or ""))
        if not self.wait_for_server():
            return False
        sim_timers.scheduler().wait_for_reader()
        rospy.loginfo("robot %d: move_base found; start vertex %d; announcing", self.id,
                      self.start_vertex)
        with self.lock:
            self.core.ready()
        return True

    def shutdown(self):
        self.scenario.publish_counters()
        with self.lock:
            self.core.shutdown()
            gh, self.gh = self.gh, None
        for t in list(self.timers):
            t.shutdown()
        if gh is not None:
            try:
                gh.cancel()
            except Exception:
                pass

    # -- ROS callbacks -> core ---------------------------------------------------------------
    def _on_results(self, msg):
        with sim_timers.batch_lock, self.lock:     # never amid a batch of due timers
            data = list(msg.data)
            self.scenario.on_results(data)
            self.core.on_results(data)
        if data:
            sim_timers.delivery.received(self.id, data[0])
        if len(data) > 2 and data[0] == MONITOR_ID and data[1] == MSG_INIT and data[2] == GO:
            sim_timers.scheduler().handled(self.id, wait=False)   # this thread delivers

    def _on_positions(self, msg):
        k = parse_robot_frame(msg.header.frame_id)
        if k is None or k == self.id:
            return
        p = msg.pose.pose.position
        with self.lock:
            self.core.on_position(k, p.x, p.y)

    def _on_transition(self, gh, seq):
        """actionlib calls this holding the goal's mutex. Taking ``self.lock`` here could
        deadlock: a thread holding ``self.lock`` may be cancelling this very goal (an
        interference, a new goal replacing it), and ``gh.cancel()`` waits for that mutex.
        So the outcome is queued and handled by the outcome thread (:meth:`_outcome_loop`);
        seen in a 16-robot run, where one agent froze for good at an interference."""
        if gh.get_comm_state() != actionlib.CommState.DONE:
            return
        self.outcomes.put((gh, seq, gh.get_goal_status()))

    def _start_outcome_thread(self):
        self.outcomes = queue.SimpleQueue()     # (goal handle, seq, status): _on_transition
        threading.Thread(target=self._outcome_loop, daemon=True,
                         name=f"robot{self.id}-goal-outcomes").start()

    def _outcome_loop(self):
        while True:
            gh, seq, status = self.outcomes.get()
            try:
                self._on_outcome(gh, seq, status)
            except Exception as e:  # a failing handler must not end the thread silently
                rospy.logerr("robot %d: error handling a goal outcome: %s", self.id, e)

    def _on_outcome(self, gh, seq, status):
        """A goal's outcome to the core, then (stale or not) the report ``sim_timers``."""
        try:
            with self.lock:
                if seq != self.core.seq:
                    return
                if gh == self.gh:        # actionlib passes a new handle each time: not `is`
                    self.gh = None
                if status != GoalStatus.SUCCEEDED:
                    rospy.logwarn("robot %d: goal to vertex %s failed (status %d)", self.id,
                                  self.core.target, status)
                self.core.on_goal_result(seq, status == GoalStatus.SUCCEEDED)
        finally:
            sim_timers.scheduler().handled(self.id)

    def _on_feedback(self, fb, seq):
        if rospy.core.is_shutdown_requested():
            return          # move_base's feedback still arriving while the node stops
        p = fb.base_position.pose.position
        odom = Odometry()
        odom.header.frame_id = self.frame_tag
        odom.pose.pose.position.x = p.x
        odom.pose.pose.position.y = p.y
        with self.lock:
            if self.scenario.may_publish() and \
                    not publish_unless_stopping(self.positions_pub, odom):
                return
            self.core.on_feedback(seq, p.x, p.y)


def publish_unless_stopping(pub, msg):
    """``pub.publish(msg)``; False, without it, if the node is stopping. rospy closes its
    topics in a pre-shutdown hook, while ``is_shutdown()`` is still False (only
    ``is_shutdown_requested()`` is True), so a callback publishing in that moment (move_base's
    feedback, a visit report) got "publish() to a closed topic", and rospy logged a traceback
    for it at the end of almost every run. Any other failure is raised."""
    try:
        pub.publish(msg)
        return True
    except rospy.ROSException:
        if rospy.core.is_shutdown_requested():
            return False
        raise


def main(argv=None):
    """Entry point of ``nodes/patrol_agent``: ``patrol_agent <map> <i>`` + private params."""
    argv = rospy.myargv(sys.argv if argv is None else argv)
    args = argv[1:]
    rid = None
    if len(args) >= 2:
        rid = args[1]
    elif len(args) == 1:
        rid = args[0]
    name = "patrol_robot" + (rid if rid is not None and rid.isdigit() else "")
    rospy.init_node(name, anonymous=rid is None or not rid.isdigit(), disable_signals=False)
    prog = "patrol_agent"
    try:
        if rid is None:
            raise AgentError("usage: patrol_agent <map> <robot_id> (with ~algorithm set)")
        try:
            robot_id = int(rid)
        except ValueError:
            raise AgentError(f"robot id: expected an integer, got '{rid}'")
        map_arg = rospy.get_param("~map", args[0] if len(args) >= 2 else None)
        if not map_arg:
            raise AgentError("map: give it as first argument or as ~map")
        alg, team_size, seed, params = read_common_params()
        agent = PatrolAgent(map_arg, robot_id, alg, team_size, seed, params)
    except AgentError as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return e.code
    return agent.run()


def main_multi(argv=None):
    """Entry point of ``nodes/patrol_agents``: several agents in one process.

    ``patrol_agents <map> <id|a-b> [...]`` with the private parameters of ``patrol_agent``;
    agent ``i`` gets seed ``~seed + i`` (``~seed`` default 0). Each agent is the same
    :class:`PatrolAgent` as in its own node, with the same topics and messages; sharing the
    process means each ``/positions`` and ``/results`` message is received once for all of
    them instead of once per agent (the N x N fan-out is what costs most with many robots).
    The node ends when the monitor's END arrives or on shutdown."""
    argv = rospy.myargv(sys.argv if argv is None else argv)
    args = argv[1:]
    rospy.init_node("patrol_agents", disable_signals=False)
    prog = "patrol_agents"
    try:
        if len(args) < 2:
            raise AgentError("usage: patrol_agents <map> <id|a-b> [...] (with ~algorithm set)")
        ids = parse_ids(args[1:])
        map_arg = rospy.get_param("~map", args[0])
        alg, team_size, seed, params = read_common_params()
        base = 0 if seed is None else seed
        agents = [PatrolAgent(map_arg, i, alg, team_size, base + i, params) for i in ids]
    except AgentError as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return e.code
    rospy.loginfo("patrol_agents: %d agents (%s) running %s", len(agents),
                  ", ".join(map(str, ids)), alg)
    threads = [threading.Thread(target=a.start, name=f"start_robot_{a.id}", daemon=True)
               for a in agents]
    for t in threads:
        t.start()
    rospy.spin()
    for a in agents:
        a.shutdown()
    return 0
