"""The monitor node (docs/monitor.md): handshake, visit processing,
metrics and result files, termination.

All measurements are made by :class:`patrolling_sim.monitor.core.MonitorCore` and written
by :class:`patrolling_sim.monitor.results.ResultWriter`; this module is the ROS glue:

- counts ``[id,10,1]``; when all N robots announced, GO ``[-1,10,100]`` (3 times, 0.5 s
  apart, and again whenever a robot announces after GO) and time zero;
- ``[id,11,v]`` -> idleness row, results block on every new complete cycle;
  ``[id,12]`` -> interference; a timeresults row every 900 s of sim time;
- ends on ``~timeout`` (sim s since GO, "TIMEOUT"), ``~cycles`` complete cycles ("CYCLES"),
  a robot silent for ``~dead_robot_timeout`` s ("FAIL"), ``/simulation_abort`` true
  ("ABORTED") or ``/simulation_running`` false ("STOPPED"): publishes END ``[-1,10,999]``,
  writes info.csv and ``<prefix>_run.yaml`` (:mod:`patrolling_sim.monitor.run_status`) and exits 0.
  Stopped from outside before its own end (SIGINT, ``rosnode kill``, roslaunch shutting
  down) it writes them too, with status "INTERRUPTED": the metrics cover a truncated run.
  The experiment runner then records the real cause (a signal, a crashed node).
- publishes live graph markers on ``/patrol_graph_markers`` (~1 Hz).
- scenarios (docs/scenarios.md): sets ``/go_time`` (ROS time of GO) so every agent fails on
  the same clock; ``[id,13,0]`` / ``[id,13,1]`` record a robot's failure / repair (a failed
  robot is exempt from the dead-robot rule, idleness is still measured over every vertex);
  with a communication model or failures configured it writes ``<prefix>_scenario.yaml``
  (:mod:`patrolling_sim.scenarios.scenario`) with the agents' message counters
  (``/scenario_counters/robot_<i>``).
"""
import math
import os
import sys
import threading
import time

import rospy
from std_msgs.msg import Int16MultiArray
from visualization_msgs.msg import MarkerArray

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.model.graph import PatrolGraph, load_graph
from patrolling_sim.monitor.core import MonitorCore
from patrolling_sim.monitor import run_status as rs
from patrolling_sim.monitor.results import ResultWriter, RunInfo, default_prefix, timestamp
from patrolling_sim.scenarios import scenario
from patrolling_sim.ros import markers

MONITOR_ID = -1
MSG_INIT, MSG_TARGET_REACHED, MSG_INTERFERENCE, MSG_FAILURE = 10, 11, 12, 13
GO, END = 100, 999
TIMERESULTS_PERIOD = 900.0     # sim s between two timeresults rows
LOOP_HZ = 10.0


class MonitorError(Exception):
    """Bad argument / parameter; ``str()`` is one line."""


def _num_param(name, default, kind=float, minimum=None):
    raw = rospy.get_param(name, default)
    try:
        val = kind(raw)
    except (TypeError, ValueError):
        raise MonitorError(f"{name}: expected a number, got {raw!r}")
    if isinstance(val, float) and math.isnan(val):
        raise MonitorError(f"{name}: expected a number, got {raw!r}")
    if minimum is not None and val < minimum:
        raise MonitorError(f"{name} must be >= {minimum}, got {raw!r}")
    return val


def _bool_param(name, default):
    raw = rospy.get_param(name, default)
    if isinstance(raw, str):
        return raw.strip().lower() in ("1", "true", "yes", "on")
    return bool(raw)


class Monitor:
    """Construct inside an initialised rospy node, then :meth:`run`."""

    def __init__(self, map_arg, alg, team_size, map_label=None):
        try:
            _, graph_path = paths.map_files(map_arg)
            self.graph = PatrolGraph(load_graph(graph_path))
        except PatrolInputError as e:
            raise MonitorError(str(e))
        self.map_name = str(rospy.get_param("~map_label", "") or map_label or
                            paths.map_name(map_arg))
        self.alg = alg
        self.n_robots = team_size
        self.results_dir = str(rospy.get_param("~results_dir", "") or
                               os.path.join(os.getcwd(), "results"))
        prefix = str(rospy.get_param("~run_prefix", "") or "")
        self.timeout = _num_param("~timeout", 0.0, minimum=0.0)
        self.max_cycles = _num_param("~cycles", 0, int, minimum=0)
        self.dead_timeout = _num_param("~dead_robot_timeout", 300.0, minimum=0.0)
        self.publish_markers = _bool_param("~publish_markers", True)
        goal_wait = _num_param("/goal_reached_wait", 0.0, minimum=0.0)
        comm_delay = _num_param("/communication_delay", 0.0, minimum=0.0)
        self._read_scenario(team_size)      # before any file is written
        stamp = timestamp()
        if not prefix:
            prefix = default_prefix(self.results_dir, self.map_name, team_size, alg,
                                    stamp=stamp)
        else:
            base = os.path.basename(prefix)
            if len(base) >= 15 and base[:8].isdigit() and base[8] == "_":
                stamp = base[:15]
        self.info = RunInfo(map=self.map_name, team_size=team_size,
                            initial_positions=str(rospy.get_param("/initial_positions",
                                                                  "default")),
                            goal_wait=goal_wait, comm_delay=comm_delay,
                            nav_module=str(rospy.get_param("/navigation_module", "ros")),
                            alg=alg,
                            algorithm_params=str(rospy.get_param("/algorithm_params", "")),
                            date=stamp)
        try:
            self.writer = ResultWriter(prefix, self.info)
        except OSError as e:
            raise MonitorError(f"~run_prefix/~results_dir: cannot create result files at "
                               f"{prefix}: {e.strerror or e}")
        self.prefix = prefix
        self.core = MonitorCore(self.graph.n, team_size)
        self.lock = threading.RLock()
        self.finished = False
        self.termination = None
        self.failed_robots = []
        self.wall_zero = None
        self.last_time_row = 0.0
        self.go_count = 0
        rospy.set_param("/simulation_running", True)
        rospy.set_param("/simulation_abort", False)
        self.pub = rospy.Publisher("/results", Int16MultiArray, queue_size=100)
        self.marker_pub = rospy.Publisher("/patrol_graph_markers", MarkerArray, queue_size=1,
                                          latch=True)
        self.sub = rospy.Subscriber("/results", Int16MultiArray, self._on_results,
                                    queue_size=1000)
        rospy.on_shutdown(self._on_shutdown)
        rospy.loginfo("monitor: %s, %d robots, %s; results prefix %s", self.map_name,
                      team_size, alg, prefix)

    def _read_scenario(self, team_size):
        """The run's scenario from ``/comm_model``, ``/attrition``, ``/scenario_seed``."""
        self.comm_spec = str(rospy.get_param("/comm_model", "perfect") or "perfect")
        self.attrition_spec = str(rospy.get_param("~attrition_spec", "") or
                                  rospy.get_param("/attrition", "none") or "none")
        self.scenario_seed = _num_param("/scenario_seed", 0, int)
        try:
            _, self.schedule = scenario.check_scenario(
                self.comm_spec, str(rospy.get_param("/attrition", "none") or "none"),
                team_size, what_comm="/comm_model", what_attr="/attrition")
        except PatrolInputError as e:
            raise MonitorError(str(e))
        self.scenario_active = not scenario.is_perfect(self.comm_spec) or bool(self.schedule)
        self.scenario_written = False

    # -- messages -----------------------------------------------------------------------
    def _send(self, *data):
        self.pub.publish(Int16MultiArray(data=list(data)))

    def _send_go(self, times=1):
        def go(_e=None):
            if not self.finished:
                self._send(MONITOR_ID, MSG_INIT, GO)
        go()
        for k in range(1, times):
            rospy.Timer(rospy.Duration(0.5 * k), go, oneshot=True)

    def _on_results(self, msg):
        d = list(msg.data)
        if len(d) < 2 or d[0] == MONITOR_ID:
            return
        rid, kind = d[0], d[1]
        with self.lock:
            # stamped under the lock: each publisher's messages come on a thread of its own,
            # and a stamp taken before the wait let a later report be recorded first
            now = rospy.get_time()
            if self.finished:
                return
            if kind == MSG_INIT and len(d) > 2 and d[2] == 1:
                if not self.core.started:
                    if rid not in self.core.ready and 0 <= rid < self.n_robots:
                        rospy.loginfo("Robot [ID = %d] is Active!", rid)
                    if self.core.robot_ready(rid):
                        rospy.loginfo("All Robots GO!")
                        self.core.start(now)
                        self.wall_zero = time.time()
                        rospy.set_param("/go_time", float(now))
                        self._send_go(3)
                elif 0 <= rid < self.n_robots:
                    self._send_go(1)       # a late announcer missed GO
            elif kind == MSG_TARGET_REACHED and len(d) > 2 and self.core.started:
                self._visit(rid, d[2], now)
            elif kind == MSG_FAILURE and len(d) > 2 and self.core.started:
                self._failure(rid, d[2], now)
            elif kind == MSG_INTERFERENCE and self.core.started:
                self.core.interference(rid, now)
                rospy.loginfo("Robot %d sent interference (total %d)", rid,
                              self.core.interferences)

    def _failure(self, rid, what, now):
        """``[id,13,0]``: robot ``rid`` failed; ``[id,13,1]``: it is back."""
        if not 0 <= rid < self.n_robots:
            return
        t = self.core.elapsed(now)
        if what == 0:
            self.core.robot_failed(rid, now)
            rospy.logwarn("[%.1f] robot %d FAILED (scenario); %d robot(s) working", t, rid,
                          self.n_robots - len(self.core.dead_robots))
        elif what == 1:
            self.core.robot_repaired(rid, now)
            rospy.logwarn("[%.1f] robot %d repaired (scenario)", t, rid)

    def _visit(self, rid, v, now):
        r = self.core.visit(rid, v, now)
        if r is None:
            rospy.logwarn("monitor: robot %d reported vertex %d outside the graph", rid, v)
            return
        if self.core.foreign_reports == 1 and not 0 <= rid < self.n_robots:
            rospy.logwarn("monitor: visit reports from robot %d, outside the team of %d: "
                          "counted in the idleness, not in the dead-robot rule", rid,
                          self.n_robots)
        self.writer.visit_row(r.t, rid, v)
        if r.idleness is not None:
            self.writer.idleness_row(now, rid, v, r.idleness, self.core.interferences)
        rospy.loginfo("[%.1f] robot %d reached %d (%s), idleness %s, cycles %d", r.t, rid, v,
                      self.alg, "-" if r.idleness is None else f"{r.idleness:.1f}", r.cycles)
        if r.new_cycle:
            if r.cycles == 1:
                self.info.algorithm_params = str(rospy.get_param("/algorithm_params",
                                                                 self.info.algorithm_params))
                try:
                    self.info.goal_wait = float(rospy.get_param("/goal_reached_wait",
                                                                self.info.goal_wait))
                except (TypeError, ValueError):
                    pass
            rospy.loginfo("Patrol completed [%d]. Write to File!", r.cycles)
            self.writer.cycle_block(self.core.stats(now), self._real_elapsed())
            if self.max_cycles and r.cycles >= self.max_cycles:
                self._finish("CYCLES", now)

    def _real_elapsed(self):
        return 0.0 if self.wall_zero is None else time.time() - self.wall_zero

    # -- loop and termination -----------------------------------------------------------
    def run(self):
        rate = rospy.Rate(LOOP_HZ)
        last_markers = -1e9
        last_params = -1e9
        while not rospy.is_shutdown() and not self.finished:
            with self.lock:
                now = rospy.get_time()          # under the lock, as every visit's stamp
                wall = time.time()
                if self.core.started and not self.finished:
                    t = self.core.elapsed(now)
                    if t - self.last_time_row >= TIMERESULTS_PERIOD:
                        self.last_time_row += TIMERESULTS_PERIOD
                        self.writer.time_row(self.core.stats(now))
                    if self.timeout > 0 and t >= self.timeout:
                        self._finish("TIMEOUT", now)
                    elif self.dead_timeout > 0:
                        # a robot failed by the scenario is not dead
                        dead = sorted(self.core.silent_robots(now, self.dead_timeout))
                        if dead:
                            rospy.logerr("monitor: robot(s) %s sent no visit for %.0f s: FAIL",
                                         ", ".join(map(str, dead)), self.dead_timeout)
                            self.failed_robots = dead
                            self._finish(rs.FAIL, now)
            if self.finished:
                break
            if wall - last_params >= 1.0:
                last_params = wall
                try:
                    if _bool_param("/simulation_abort", False):
                        self._finish(rs.ABORTED, now)
                    elif not _bool_param("/simulation_running", True):
                        self._finish("STOPPED", now)
                except (ConnectionError, OSError, rospy.ROSException):
                    pass
            if self.publish_markers and wall - last_markers >= 1.0:
                last_markers = wall
                self._publish_markers(now)
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break
        if self.finished and not rospy.is_shutdown():
            # repeat END once and let the last messages go out before the node exits
            time.sleep(0.25)
            self._send(MONITOR_ID, MSG_INIT, END)
            time.sleep(0.25)     # the agents' last counters arrive meanwhile
        self._write_scenario()
        return 0

    def _write_scenario(self):
        """``<prefix>_scenario.yaml`` (once), when the run has a scenario."""
        with self.lock:
            if self.scenario_written or not self.scenario_active:
                return
            self.scenario_written = True
            try:
                raw = rospy.get_param("/scenario_counters", {})
            except (ConnectionError, OSError, rospy.ROSException):
                raw = {}
            counters = {}
            for key, value in (raw or {}).items():
                if str(key).startswith("robot_") and str(key)[6:].isdigit():
                    counters[int(str(key)[6:])] = dict(value)
            try:
                path = scenario.write_scenario(
                    self.prefix, self.comm_spec, self.attrition_spec, self.schedule,
                    list(self.core.failures), counters, seed=self.scenario_seed, mode="ros")
                rospy.loginfo("monitor: scenario file %s written", path)
            except OSError as e:
                rospy.logerr("monitor: cannot write %s_scenario.yaml: %s", self.prefix, e)

    def _publish_markers(self, now):
        with self.lock:
            idl = self.core.current_idleness(now) if self.core.started else [0.0] * self.graph.n
        self.marker_pub.publish(markers.build_marker_array(self.graph, idl,
                                                           stamp=rospy.Time.now()))

    def _finish(self, termination, now):
        """End of the run: END to the agents, info.csv, flags."""
        with self.lock:
            if self.finished:
                return
            self.finished = True
            self.termination = termination
            try:
                self._send(MONITOR_ID, MSG_INIT, END)
            except rospy.ROSException:
                pass
            try:
                rospy.set_param("/simulation_running", False)
            except (ConnectionError, OSError, rospy.ROSException):
                pass
            self._write_info(termination, now)

    def _write_info(self, termination, now):
        stats = self.core.stats(now)
        path = self.writer.write_info(stats, self._real_elapsed(), termination)
        self.writer.close()
        reasons = {rs.TIMEOUT: f"the timeout of {self.timeout:g} sim s was reached",
                   rs.CYCLES: f"{self.max_cycles} complete patrol cycles done",
                   rs.FAIL: f"robot(s) {', '.join(map(str, self.failed_robots))} sent no "
                            f"visit for {self.dead_timeout:g} sim s",
                   rs.ABORTED: "/simulation_abort was set",
                   rs.STOPPED: "/simulation_running was set false",
                   rs.INTERRUPTED: "the monitor was stopped from outside before the run's "
                                   "end (signal or shutdown)"}
        try:
            rs.write_run_yaml(self.prefix, {
                "status": termination, "reason": reasons.get(termination, ""),
                "culprit": None, "robots": list(self.failed_robots), "signal": None,
                "sim_time": round(stats.elapsed, 1), "wall_time": None,
                "real_time_since_go": round(self._real_elapsed(), 1), "exit_code": None,
                "longest_silence": [round(x, 1) for x in self.core.silences(now)],
                "written_by": "monitor"})
        except OSError as e:
            rospy.logerr("monitor: cannot write %s_run.yaml: %s", self.prefix, e)
        msg = f"Info file {path} saved."
        rospy.loginfo("%s", msg)
        print(msg, flush=True)
        print("Monitor closed.", flush=True)

    def _on_shutdown(self):
        with self.lock:
            if self.finished:
                return
            self.finished = True
            self.termination = rs.INTERRUPTED
            try:
                now = rospy.get_time()
            except Exception:
                now = self.core.time_zero or 0.0
            self._write_info(rs.INTERRUPTED, now)
        self._write_scenario()


def main(argv=None):
    """Entry point of ``nodes/monitor``: ``monitor <map> <ALG> <N>`` + private params."""
    argv = rospy.myargv(sys.argv if argv is None else argv)
    args = argv[1:]
    rospy.init_node("monitor")
    prog = "monitor"
    try:
        if len(args) != 3:
            raise MonitorError(f"usage: monitor <map> <ALG> <N> (got {len(args)} arguments)")
        map_arg = str(rospy.get_param("~map", "") or args[0])
        alg, n_raw = args[1], args[2]
        try:
            n = int(n_raw)
        except ValueError:
            raise MonitorError(f"N: expected a positive integer, got '{n_raw}'")
        if n < 1:
            raise MonitorError(f"N: team size must be >= 1, got {n}")
        mon = Monitor(map_arg, alg, n, map_label=paths.map_name(args[0]))
    except MonitorError as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return 2
    return mon.run()
