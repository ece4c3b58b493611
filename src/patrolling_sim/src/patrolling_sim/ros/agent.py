"""The PatrolAgent node: one robot's life cycle around a patrolling strategy
(patrolling_sim_facts.md sections 2.3-2.8).

The node is event driven: every callback (``/results``, ``/positions``, move_base
transitions and feedback, timers) takes ``self.lock``, updates the state and returns; waits
(goal wait, interference pause, back-up manoeuvre, communication delay, auction deadlines)
are one-shot timers on ROS time, never sleeps inside a callback.

Life cycle:
    1. load the graph, read ``/initial_pos``, start vertex = nearest vertex (|dx|+|dy|);
    2. wait for ``robot_i/move_base`` (logging every 5 s), then announce ``[i,10,1]`` on
       ``/results`` every 2 s until the monitor's GO ``[-1,10,100]``;
    3. after GO and a random U(0,1) s delay: clear costmaps, ``strategy.start``, report the
       start vertex ``[i,11,start]``, send the first goal;
    4. on SUCCEEDED: wait ``/goal_reached_wait``, ``strategy.on_arrival``, report
       ``[i,11,v]``, send the next goal; on a failure not caused by our own cancel: back-up,
       clear costmaps, resend the same goal (at most 3 times), then
       ``strategy.on_goal_failed``;
    5. ends on the monitor's END ``[-1,10,999]`` or on shutdown (SIGINT).
"""
import math
import random
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

from .. import algorithms, paths
from ..algorithms.base import (INT16_MAX, MSG_INIT, MSG_INTERFERENCE, MSG_TARGET_REACHED,
                               Driver, StrategyContext)
from ..errors import PatrolInputError
from ..graph import PatrolGraph, load_graph

MONITOR_ID = -1
GO = 100
END = 999
ANNOUNCE_PERIOD = 2.0          # s between [i,10,1] announcements
SERVER_LOG_PERIOD = 5.0        # s between "waiting for move_base" log lines
MAX_RESENDS = 3                # resends of a failed goal before on_goal_failed
INTERFERENCE_DIST = 2.0        # m
INTERFERENCE_PERIOD = 10.0     # s between two detections of the same robot
INTERFERENCE_PAUSE = 3.0       # s stopped after a detection
INT16_MIN = -32768

_ROBOT_FRAME = re.compile(r"robot_(\d+)(?:/|$)")


class AgentError(Exception):
    """Fatal start-up problem; ``str()`` is one line, the node exits with ``code``."""

    def __init__(self, message, code=2):
        super().__init__(message)
        self.code = code


def parse_robot_frame(frame_id):
    """Robot index from a ``/positions`` frame id ``robot_<i>/map`` (None if absent)."""
    m = _ROBOT_FRAME.search(frame_id or "")
    return int(m.group(1)) if m else None


def clamp_int16(data):
    """(clamped list, True if any value had to be clamped)."""
    out, clamped = [], False
    for x in data:
        x = int(x)
        if x > INT16_MAX:
            x, clamped = INT16_MAX, True
        elif x < INT16_MIN:
            x, clamped = INT16_MIN, True
        out.append(x)
    return out, clamped


def start_vertex_from(graph, initial_pos, robot_id):
    """Start vertex of ``robot_id`` from the flat ``/initial_pos`` list (x0,y0,x1,y1,...)."""
    try:
        flat = [float(x) for x in initial_pos]
    except (TypeError, ValueError):
        raise AgentError(f"/initial_pos: expected a flat list of numbers, got {initial_pos!r}")
    if len(flat) < 2 * (robot_id + 1):
        raise AgentError(f"/initial_pos has {len(flat) // 2} positions, robot {robot_id} "
                         f"needs at least {robot_id + 1}")
    x, y = flat[2 * robot_id], flat[2 * robot_id + 1]
    return graph.nearest_vertex(x, y), (x, y)


def load_registry():
    """Import every module of :mod:`patrolling_sim.algorithms` so that each registers its
    strategy; returns the registry (short name -> class)."""
    import importlib
    import pkgutil
    for mod in pkgutil.iter_modules(algorithms.__path__):
        if mod.name != "base" and not mod.name.startswith("_"):
            try:
                importlib.import_module(f"{algorithms.__name__}.{mod.name}")
            except ImportError as e:
                rospy.logwarn("algorithm module %s not loaded: %s", mod.name, e)
    return algorithms.REGISTRY


def make_strategy(name, ctx):
    """Create the strategy registered as ``name`` (the registry is the only source, so a
    user-written strategy class only has to register itself)."""
    registry = load_registry()
    if name not in registry:
        known = ", ".join(sorted(registry)) or "none"
        raise AgentError(f"~algorithm: unknown algorithm '{name}' (known: {known})")
    create = getattr(algorithms, "create", None)
    try:
        return create(name, ctx) if create else registry[name](ctx)
    except PatrolInputError as e:
        raise AgentError(str(e))


class RosDriver(Driver):
    """The :class:`Driver` a strategy sees inside the agent node."""

    def __init__(self, agent):
        self.agent = agent

    def now(self):
        return rospy.get_time()

    def send(self, data):
        self.agent.send_algorithm_message(list(data))

    def call_later(self, delay, fn):
        self.agent.call_later(delay, fn)

    def redirect(self, vertex):
        self.agent.redirect(vertex)


class PatrolAgent:
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

        self.goal_wait = self._float_param("/goal_reached_wait", 0.0, minimum=0.0)
        self.comm_delay = self._float_param("/communication_delay", 0.0, minimum=0.0)
        self.loss_rate = self._float_param("/lost_message_rate", 0.0, minimum=0.0)
        if self.loss_rate > 1.0:
            raise AgentError(f"/lost_message_rate must be in [0, 1], got {self.loss_rate}")

        seed = self.id if seed is None else int(seed)
        # separate generators: message loss and start jitter never perturb decisions
        self.loss_rng = random.Random(seed * 7919 + 1)
        self.jitter_rng = random.Random(seed * 7919 + 2)

        self.lock = threading.RLock()
        self.driver = RosDriver(self)
        ctx = StrategyContext(graph=self.graph, robot_id=self.id, team_size=self.team_size,
                              map_name=self.map_name, rng=random.Random(seed),
                              driver=self.driver, params=dict(params or {}),
                              start_position=tuple(self.start_xy))
        self.strategy = make_strategy(algorithm, ctx)

        # state
        self.phase = "init"            # init, ready, starting, patrol, ended
        self.started = False
        self.pending_msgs = []         # algorithm messages received between GO and start
        self.target = None             # vertex of the active (or paused) goal
        self.gh = None                 # current ClientGoalHandle
        self.token = 0                 # bumps on every send/cancel: stale callbacks ignored
        self.resends = 0
        self.busy = False              # waiting (goal wait / back-up / interference pause)
        self.own_pos = tuple(self.start_xy)
        self.team_pos = {}             # robot id -> (x, y)
        self.last_interference = -1e9
        self.timers = set()
        self.clamp_warned = False

        ns = f"robot_{self.id}"
        self.results_pub = rospy.Publisher("/results", Int16MultiArray, queue_size=100)
        self.positions_pub = rospy.Publisher("/positions", Odometry, queue_size=1)
        self.cmd_pub = rospy.Publisher(f"{ns}/cmd_vel", Twist, queue_size=1)
        self.clear_name = f"{ns}/move_base/clear_costmaps"
        self.server_name = rospy.resolve_name(f"{ns}/move_base")
        self.client = actionlib.ActionClient(self.server_name, MoveBaseAction)
        self.frame_tag = f"robot_{self.id}/map"
        rospy.Subscriber("/results", Int16MultiArray, self._on_results, queue_size=100)
        rospy.Subscriber("/positions", Odometry, self._on_positions, queue_size=10)

    # -- helpers -------------------------------------------------------------------------
    @staticmethod
    def _float_param(name, default, minimum=None):
        raw = rospy.get_param(name, default)
        try:
            val = float(raw)
        except (TypeError, ValueError):
            raise AgentError(f"{name}: expected a number, got {raw!r}")
        if minimum is not None and (val < minimum or math.isnan(val)):
            raise AgentError(f"{name} must be >= {minimum}, got {raw!r}")
        return val

    def call_later(self, delay, fn):
        """Run ``fn()`` (under the lock) after ``delay`` s of ROS time, without blocking."""
        holder = {}

        def fire(_event):
            with self.lock:           # the creator holds the lock until holder is filled
                self.timers.discard(holder.get("t"))
                if rospy.is_shutdown() or self.phase == "ended":
                    return
                try:
                    fn()
                except Exception as e:  # a failing callback must not kill the node silently
                    rospy.logerr("robot %d: error in timed callback: %s", self.id, e)
                    raise

        with self.lock:
            t = rospy.Timer(rospy.Duration(max(float(delay), 1e-3)), fire, oneshot=True)
            holder["t"] = t
            self.timers.add(t)
        return t

    def publish(self, data):
        data, clamped = clamp_int16(data)
        if clamped and not self.clamp_warned:
            self.clamp_warned = True
            rospy.logwarn("robot %d: /results payload clamped to int16 (type %s)", self.id,
                          data[1] if len(data) > 1 else "?")
        self.results_pub.publish(Int16MultiArray(data=data))

    def send_algorithm_message(self, data):
        """Driver.send: types 10/11/12 go out at once; algorithm messages are dropped with
        probability /lost_message_rate and delayed by /communication_delay."""
        if len(data) > 1 and data[1] in (MSG_INIT, MSG_TARGET_REACHED, MSG_INTERFERENCE):
            self.publish(data)
            return
        if self.loss_rate > 0 and self.loss_rng.random() < self.loss_rate:
            rospy.logdebug("robot %d: message %s lost", self.id, data[:3])
            return
        if self.comm_delay > 0.001:
            self.call_later(self.comm_delay, lambda: self.publish(data))
        else:
            self.publish(data)

    def clear_costmaps(self):
        """Call robot_i/move_base/clear_costmaps if it exists, in a background thread."""
        def work():
            try:
                rospy.wait_for_service(self.clear_name, timeout=1.0)
                rospy.ServiceProxy(self.clear_name, Empty)()
            except (rospy.ROSException, rospy.ServiceException):
                rospy.logdebug("robot %d: no %s", self.id, self.clear_name)
        threading.Thread(target=work, daemon=True).start()

    # -- start-up ------------------------------------------------------------------------
    def wait_for_server(self):
        name = self.server_name
        while not rospy.is_shutdown() and self.phase != "ended":
            if self.client.wait_for_server(rospy.Duration(SERVER_LOG_PERIOD)):
                return True
            rospy.loginfo("robot %d: waiting for the %s action server...", self.id, name)
        return False

    def run(self):
        """Life cycle of a single-agent node: :meth:`start`, spin until END or shutdown."""
        if self.start():
            rospy.spin()
        self.shutdown()
        return 0

    def start(self):
        """Wait for ``robot_i/move_base``, then announce ``[i,10,1]`` every 2 s until GO
        (callbacks do the rest). Returns False if the node shut down meanwhile."""
        if self.id == 0 or not rospy.has_param("/algorithm_params"):
            rospy.set_param("/algorithm_params", str(self.strategy.algorithm_params or ""))
        if not self.wait_for_server():
            return False
        with self.lock:
            if self.phase == "init":
                self.phase = "ready"
        rospy.loginfo("robot %d: move_base found; start vertex %d; announcing", self.id,
                      self.start_vertex)
        self._announce(None)
        self.announce_timer = rospy.Timer(rospy.Duration(ANNOUNCE_PERIOD), self._announce)
        return True

    def _announce(self, _event):
        if self.phase == "ready":
            self.publish([self.id, MSG_INIT, 1])
        elif getattr(self, "announce_timer", None) is not None:
            self.announce_timer.shutdown()

    def shutdown(self):
        with self.lock:
            self.phase = "ended"
            gh, self.gh = self.gh, None
            self.token += 1
        for t in list(self.timers):
            t.shutdown()
        if gh is not None:
            try:
                gh.cancel()
            except Exception:
                pass

    # -- /results and /positions ----------------------------------------------------------
    def _on_results(self, msg):
        data = list(msg.data)
        if len(data) < 2 or data[0] == self.id:
            return
        with self.lock:
            if data[0] == MONITOR_ID and data[1] == MSG_INIT and len(data) > 2:
                if data[2] == GO and self.phase in ("init", "ready"):
                    self.phase = "starting"
                    delay = self.jitter_rng.uniform(0.0, 1.0)
                    rospy.loginfo("robot %d: GO received, starting in %.2f s", self.id, delay)
                    self.call_later(delay, self._begin)
                elif data[2] == END:
                    rospy.loginfo("robot %d: END received from the monitor", self.id)
                    self.phase = "ended"
                    rospy.signal_shutdown("monitor END")
                return
            if data[1] >= 30 and self.phase in ("starting", "patrol"):
                if self.started:
                    self.strategy.on_message(data, rospy.get_time())
                else:
                    self.pending_msgs.append(data)

    def _on_positions(self, msg):
        k = parse_robot_frame(msg.header.frame_id)
        if k is None or k == self.id:
            return
        p = msg.pose.pose.position
        with self.lock:
            self.team_pos[k] = (p.x, p.y)

    # -- patrol loop ----------------------------------------------------------------------
    def _begin(self):
        now = rospy.get_time()
        self.clear_costmaps()
        self.strategy.start(self.start_vertex, now)
        self.started = True
        self.phase = "patrol"
        pending, self.pending_msgs = self.pending_msgs, []
        for data in pending:
            self.strategy.on_message(data, now)
        nxt = self.strategy.next_vertex(now)
        self.publish([self.id, MSG_TARGET_REACHED, self.start_vertex])
        self.strategy.send_results(now)
        self._go_next(nxt)

    def _go_next(self, v):
        if v is None:
            # the strategy has not decided yet (e.g. waiting for an auction): ask again soon
            self.call_later(0.5, lambda: self.target is None and self._go_next(
                self.strategy.next_vertex(rospy.get_time())))
            self.target = None
            return
        self.resends = 0
        self.send_goal(int(v))

    def send_goal(self, v):
        """Send a move_base goal to vertex ``v`` (replaces any current goal)."""
        if self.phase == "ended":
            return
        if self.gh is not None:
            self._cancel_current()
        self.token += 1
        token = self.token
        self.target = v
        self.busy = False
        goal = MoveBaseGoal()
        goal.target_pose.header.frame_id = "map"
        goal.target_pose.header.stamp = rospy.Time.now()
        x, y = self.graph.pos[v]
        goal.target_pose.pose.position.x = float(x)
        goal.target_pose.pose.position.y = float(y)
        goal.target_pose.pose.orientation.w = 1.0
        self.gh = self.client.send_goal(
            goal,
            transition_cb=lambda gh: self._on_transition(gh, token),
            feedback_cb=lambda gh, fb: self._on_feedback(fb, token))

    def _cancel_current(self):
        """Self-cancel: the done callback of the cancelled goal is ignored (no back-up)."""
        gh, self.gh = self.gh, None
        self.token += 1
        if gh is not None:
            try:
                gh.cancel()
            except Exception as e:
                rospy.logdebug("robot %d: cancel failed: %s", self.id, e)

    def redirect(self, vertex):
        """Driver.redirect: abandon the current goal, head to ``vertex``."""
        with self.lock:
            if self.phase != "patrol":
                return
            self.resends = 0
            self.send_goal(int(vertex))

    def _on_transition(self, gh, token):
        if gh.get_comm_state() != actionlib.CommState.DONE:
            return
        with self.lock:
            if token != self.token or self.phase != "patrol":
                return
            status = gh.get_goal_status()
            self.gh = None
            v = self.target
            if status == GoalStatus.SUCCEEDED:
                self.busy = True
                if self.goal_wait > 0:
                    self.call_later(self.goal_wait, lambda: self._arrived(v, token))
                else:
                    self._arrived(v, token)
            else:
                rospy.logwarn("robot %d: goal to vertex %d failed (status %d)", self.id, v,
                              status)
                self._goal_failed(v, token)

    def _arrived(self, v, token):
        if token != self.token or self.phase != "patrol":
            return
        now = rospy.get_time()
        self.strategy.on_arrival(v, now)
        if token != self.token:        # the strategy redirected us meanwhile
            self.publish([self.id, MSG_TARGET_REACHED, v])
            return
        nxt = self.strategy.next_vertex(now)
        self.publish([self.id, MSG_TARGET_REACHED, v])
        self.strategy.send_results(now)
        if token != self.token:
            return
        self._go_next(nxt)

    def _goal_failed(self, v, token):
        """Back-up (short reverse + rotate), clear costmaps, then resend or give up."""
        self.busy = True
        self._backup()
        self.clear_costmaps()

        def after_backup():
            if token != self.token or self.phase != "patrol":
                return
            if self.resends < MAX_RESENDS:
                self.resends += 1
                rospy.loginfo("robot %d: resending goal %d (%d/%d)", self.id, v, self.resends,
                              MAX_RESENDS)
                resends = self.resends
                self.send_goal(v)
                self.resends = resends
            else:
                nxt = self.strategy.on_goal_failed(v, rospy.get_time())
                rospy.loginfo("robot %d: giving up on vertex %d, going to %s", self.id, v, nxt)
                self._go_next(nxt)

        self.call_later(1.0, after_backup)

    def _backup(self):
        def twist(lin, ang):
            t = Twist()
            t.linear.x = lin
            t.angular.z = ang
            return t
        self.cmd_pub.publish(twist(-0.1, 0.0))
        self.call_later(0.2, lambda: self.cmd_pub.publish(twist(0.0, 0.5)))
        self.call_later(0.95, lambda: self.cmd_pub.publish(twist(0.0, 0.0)))

    def _on_feedback(self, fb, token):
        p = fb.base_position.pose.position
        odom = Odometry()
        odom.header.frame_id = self.frame_tag
        odom.pose.pose.position.x = p.x
        odom.pose.pose.position.y = p.y
        self.positions_pub.publish(odom)
        with self.lock:
            if token != self.token or self.phase != "patrol":
                return
            self.own_pos = (p.x, p.y)
            now = rospy.get_time()
            if now - self.last_interference < INTERFERENCE_PERIOD:
                return
            for j, (x, y) in self.team_pos.items():
                if j < self.id and (x - p.x) ** 2 + (y - p.y) ** 2 <= INTERFERENCE_DIST ** 2:
                    self._interference(j, now)
                    break

    def _interference(self, other, now):
        """Report [i,12], stop for 3 s (timer), then resend the same goal."""
        self.last_interference = now
        v = self.target
        rospy.loginfo("robot %d: interference with robot %d", self.id, other)
        self.publish([self.id, MSG_INTERFERENCE])
        self._cancel_current()
        self.busy = True
        token = self.token
        resends = self.resends

        def resume():
            if token != self.token or self.phase != "patrol":
                return
            self.send_goal(v)
            self.resends = resends

        self.call_later(INTERFERENCE_PAUSE, resume)


def _optional_int_param(name):
    """Private parameter ``name`` as an int, None if unset; AgentError if not an integer."""
    value = rospy.get_param(name, None)
    if value is None:
        return None
    try:
        return int(value)
    except (TypeError, ValueError):
        raise AgentError(f"{name}: expected an integer, got {value!r}") from None


def _read_common_params():
    """(algorithm, team_size, seed, params) from the node's private parameters."""
    if not rospy.has_param("~algorithm"):
        known = ", ".join(sorted(load_registry()))
        raise AgentError(f"~algorithm is required (known: {known})")
    alg = str(rospy.get_param("~algorithm"))
    team_size = _optional_int_param("~team_size")
    seed = _optional_int_param("~seed")
    params = rospy.get_param("~params", {})
    if not isinstance(params, dict):
        raise AgentError(f"~params: expected a dictionary, got {params!r}")
    return alg, team_size, seed, params


def main(argv=None):
    """Entry point of ``nodes/patrol_agent``: ``patrol_agent <map> <i>`` + private params."""
    import sys
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
        alg, team_size, seed, params = _read_common_params()
        agent = PatrolAgent(map_arg, robot_id, alg, team_size, seed, params)
    except AgentError as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return e.code
    return agent.run()


def parse_ids(tokens):
    """Robot ids from ``['0', '2', '5-7']`` -> [0, 2, 5, 6, 7] (sorted, no duplicates)."""
    ids = set()
    for tok in tokens:
        m = re.fullmatch(r"(\d+)(?:-(\d+))?", tok)
        if not m:
            raise AgentError(f"robot id: expected an integer or a range a-b, got '{tok}'")
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        if b < a:
            raise AgentError(f"robot id range '{tok}' is empty")
        ids.update(range(a, b + 1))
    return sorted(ids)


def main_multi(argv=None):
    """Entry point of ``nodes/patrol_agents``: several agents in one process.

    ``patrol_agents <map> <id|a-b> [...]`` with the private parameters of ``patrol_agent``;
    agent ``i`` gets seed ``~seed + i`` (``~seed`` default 0). Each agent is the same
    :class:`PatrolAgent` as in its own node, with the same topics and messages; sharing the
    process means each ``/positions`` and ``/results`` message is received once for all of
    them instead of once per agent (the N x N fan-out is what costs most with many robots).
    The node ends when the monitor's END arrives or on shutdown."""
    import sys
    argv = rospy.myargv(sys.argv if argv is None else argv)
    args = argv[1:]
    rospy.init_node("patrol_agents", disable_signals=False)
    prog = "patrol_agents"
    try:
        if len(args) < 2:
            raise AgentError("usage: patrol_agents <map> <id|a-b> [...] (with ~algorithm set)")
        ids = parse_ids(args[1:])
        map_arg = rospy.get_param("~map", args[0])
        alg, team_size, seed, params = _read_common_params()
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
