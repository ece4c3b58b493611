"""Graph-level discrete-event simulator: run a patrolling experiment in seconds, no ROS.

Every robot is the same :class:`~patrolling_sim.agent.core.PatrolAgentCore` as in the ROS
PatrolAgent node (same strategies, same life cycle and order of events, see
``docs/protocol.md``), driven here by simulated time; the monitor metrics
(:class:`~patrolling_sim.monitor.core.MonitorCore`) and result files
(:class:`~patrolling_sim.monitor.results.ResultWriter`, nav_module ``graph``) are the ROS mode's, so
graph-mode results load in the report next to ROS runs.

The world this module adds (see ``docs/protocol.md``, "Graph mode"):

- motion: a robot is a point moving at ``speed`` along the shortest graph path to its goal
  (``travel="graph"``; positions interpolated along the edges), or in a straight line from
  where it stands (``travel="euclidean"``); a trip takes at least ``MIN_TRIP`` s;
- GO at t = 0 for every robot (all navigation servers are up at once);
- navigation failure: a goal the graph cannot reach fails at once, and any goal fails with
  probability ``goal_fail`` at a uniformly drawn point of its trip (one seeded generator);
  the core then backs up, resends, and gives up after three resends, as in ROS mode;
- positions: every ``FEEDBACK_PERIOD`` s each moving robot publishes its position and its
  core evaluates interference (the 2 m / 10 s / 3 s rule), unless ``interference`` is off;
- messages: visit reports and interferences reach the monitor at once; algorithm messages
  reach the other robots after the core's delay and loss.

Deterministic: the same inputs and seed give the same files (apart from wall-clock fields).
"""
import heapq
import itertools
import math
import os
import random
import time
from typing import Callable, Optional, Sequence

from patrolling_sim.common import paths
from patrolling_sim.monitor import run_status
from patrolling_sim.agent.core import FIRST_ALGORITHM_TYPE, GO, MONITOR_ID
from patrolling_sim.agent.factory import agent_seed, build_agent
from patrolling_sim.algorithms.base import MSG_FAILURE
from patrolling_sim.common.protocol import MSG_INIT, MSG_INTERFERENCE, MSG_TARGET_REACHED
from patrolling_sim.common.errors import NoSpaceError, PatrolInputError, is_no_space
from patrolling_sim.graphsim.config import (FEEDBACK_PERIOD, TIMERESULTS_PERIOD, WRITE_FLUSH_EVERY,
                                            GraphSimConfig, config_yaml)
from patrolling_sim.graphsim.feedback import FeedbackTicks
from patrolling_sim.graphsim.motion import Robot
from patrolling_sim.graphsim.starts import start_vertices_of
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.monitor.core import MonitorCore, Stats
from patrolling_sim.monitor.results import (ResultWriter, RunInfo, claim_prefix, default_prefix,
                                            hostname)
from patrolling_sim.scenarios.scenario import check_scenario, is_perfect, write_scenario
from patrolling_sim.startpos.explicit import initpos_label
from patrolling_sim.startpos.optimised import write_start_poses
from spqrel_nav_lite.mapio import load_map


class GraphSimulator(FeedbackTicks):
    """One run. Use :meth:`run`; see the module docstring for the model. A caller that
    steps the run (a learning environment) calls :meth:`begin`, :meth:`advance` as often
    as it needs, then :meth:`finish`; ``strategy_class`` replaces the registered ``cfg.alg``
    (which still names the run)."""

    def __init__(self, cfg: GraphSimConfig, start_vertices: Optional[Sequence[int]] = None,
                 pgraph: Optional[PatrolGraph] = None, prefix: Optional[str] = None,
                 log: Optional[Callable[[str], None]] = None, strategy_class=None):
        self.cfg = cfg.validate()
        #: the robots' strategy class instead of the registered ``cfg.alg`` (None: that one)
        self.strategy_class = strategy_class
        self.wall0 = time.monotonic()
        self.map_name = paths.map_name(cfg.map)
        if pgraph is None:
            pgraph = PatrolGraph.load(paths.map_files(cfg.map)[1])
        self.g = pgraph
        self.rng = random.Random(cfg.seed)     # the world's own draws (goal failures)
        if start_vertices is None:
            start_vertices = start_vertices_of(cfg, pgraph)
        if len(start_vertices) != cfg.robots:
            raise PatrolInputError(f"need {cfg.robots} start vertices, got {len(start_vertices)}")
        self.start_vertices = list(start_vertices)
        self.t = 0.0
        self._events = []
        self._seq = itertools.count()
        self.monitor = MonitorCore(self.g.n, cfg.robots)
        #: (x, y) of every vertex as Python floats (the motion's hot paths read these)
        self.vertex_xy = [(float(x), float(y)) for x, y in pgraph.pos]
        self.robots = [Robot(self, i, v) for i, v in enumerate(self.start_vertices)]
        #: positions robots have published while moving (shared by all cores)
        self.team_pos = {}
        #: skip feedback work that cannot find an interference (same results, faster)
        self.skip_idle_ticks = True
        self._tick = math.inf                         # next feedback tick (the first trip)
        self._last_tick = -1                          # last tick run
        #: (start vertex, goal) -> the pieces of that trip (graph_motion.Robot._route)
        self.trip_cache = {}
        #: per robot, the next feedback tick at which it must be evaluated (_feedback_lazy)
        self._due = [math.inf] * cfg.robots
        #: per robot i, per robot j < i: the next tick at which the two may be within
        #: INTERFERENCE_DIST (0: not measured yet, due at once)
        self._pair_due = [[0] * i for i in range(cfg.robots)]
        #: most two robots can close in on each other in one tick (m): a robot moves along
        #: the graph at ``speed`` cost per second, which is faster in the plane where an
        #: edge's cost is below its straight length (graph.max_stretch)
        self._closing_per_tick = 2.0 * cfg.speed * FEEDBACK_PERIOD * pgraph.max_stretch()
        self.prefix = prefix
        self.log = log or (lambda s: None)
        self.termination = None
        self.writer = None
        self._init_scenario()

    def _init_scenario(self):
        """The run's scenario (docs/scenarios.md): the failure schedule, and whether the
        communication model is applied (then every core has its own view of the teammates'
        positions, fed through the model, and every feedback tick is simulated)."""
        cfg = self.cfg
        self.perfect_comm = is_perfect(cfg.comm)
        self.occupancy = None
        if (cfg.comm or "").strip().lower().startswith("range"):
            self.occupancy = load_map(paths.map_files(cfg.map)[0])
        _, self.schedule_failures = check_scenario(
            cfg.comm, cfg.attrition, cfg.robots,
            cfg.duration if cfg.duration > 0 else math.inf, cfg.seed)
        self.scenario = not self.perfect_comm or bool(self.schedule_failures)
        if not self.perfect_comm:
            self.skip_idle_ticks = False

    def true_position(self, k):
        """Where robot ``k`` is now (m): the range model's truth."""
        r = self.robots[k]
        return r.position(self.t)[:2] if r.pieces is not None else r.xy

    def _share_position(self, rid, xy):
        """Robot ``rid`` published ``xy`` on /positions: each teammate's core receives it
        through its communication model (nothing with ``positions`` off)."""
        if not self.cfg.positions:
            return
        for r in self.robots:
            if r.id != rid and r.core is not None:
                r.core.on_position(rid, xy[0], xy[1])

    @property
    def messages_sent(self):
        """Algorithm messages the robots sent (before loss)."""
        return sum(r.core.messages_sent for r in self.robots if r.core is not None)

    @property
    def messages_lost(self):
        return sum(r.core.messages_lost for r in self.robots if r.core is not None)

    # -- event queue ------------------------------------------------------------------------
    def schedule(self, t, fn):
        heapq.heappush(self._events, (t, next(self._seq), fn))

    def publish(self, sender, data):
        """A message on /results: visit reports and interferences go to the monitor at once;
        algorithm messages reach every other robot as an event at the same time."""
        kind = data[1] if len(data) > 1 else None
        if kind == MSG_TARGET_REACHED and len(data) > 2:
            self._report(sender, data[2])
        elif kind == MSG_FAILURE and len(data) > 2:
            if data[2] == 0:
                self.monitor.robot_failed(sender, self.t)
                self.log(f"t={self.t:.1f} s: robot {sender} failed")
            else:
                self.monitor.robot_repaired(sender, self.t)
                self.log(f"t={self.t:.1f} s: robot {sender} repaired")
        elif kind == MSG_INTERFERENCE:
            self.monitor.interference(sender, self.t)
        elif kind != MSG_INIT:
            self.schedule(self.t, lambda: self._broadcast(sender, data))

    def _broadcast(self, sender, data):
        """``data`` reaches every other robot, in id order. One event for all receivers is
        the same as one event each: those would have consecutive sequence numbers, so no
        other event runs between them (what a receiver schedules at this time runs after the
        last receiver); the run loop's cycle limit is checked after each receiver, as it
        would be after each event."""
        cycles = self.cfg.cycles
        data = tuple(data)      # one read-only copy for every receiver (AgentCore._hand_over)
        # an algorithm message over perfect links: each core's direct entry (the same
        # handling as on_results, a third of a message-heavy run's time went to the calls)
        direct = len(data) > 1 and data[1] >= FIRST_ALGORITHM_TYPE
        now = self.t
        for r in self.robots:
            if r.id != sender:
                core = r.core
                if direct and core.comm is None:
                    core.hear(data, now)
                else:
                    core.on_results(data)
                if cycles and self.monitor.cycles >= cycles:
                    return

    def stood(self, robot):
        """``robot`` stopped at ``robot.xy``: that is its last published position."""
        self.team_pos[robot.id] = robot.xy
        if not self.perfect_comm:
            self._share_position(robot.id, robot.xy)

    # -- monitor ----------------------------------------------------------------------------
    def _report(self, rid, v):
        r = self.monitor.visit(rid, v, self.t)
        if r is None:
            return
        if self.writer:
            self.writer.visit_row(r.t, rid, v)
            if r.idleness is not None:
                self.writer.idleness_row(self.t, rid, v, r.idleness, self.monitor.interferences)
        if r.new_cycle:
            if self.writer:
                self.writer.cycle_block(self.monitor.stats(self.t), time.monotonic() - self.wall0)
            self.log(f"t={self.t:.1f} s: patrol cycle {r.cycles} complete")

    def _make_core(self, robot):
        cfg = self.cfg
        sv = self.start_vertices[robot.id]
        params = cfg.strategy_params()
        params.setdefault("start_vertices", self.start_vertices)
        robot.core = build_agent(robot, self.g, robot.id, cfg.robots, self.map_name, cfg.alg,
                                 sv, robot.xy, seed=agent_seed(cfg.seed, robot.id),
                                 params=params, goal_wait=cfg.gwait,
                                 comm_delay=cfg.comm_delay, loss=cfg.loss, comm=cfg.comm,
                                 occupancy=self.occupancy, positions=self.true_position,
                                 silence_check=bool(self.schedule_failures),
                                 strategy_class=self.strategy_class)
        robot.core.strategy.clock_zero = -cfg.go_time    # GO is t = 0 here
        if self.perfect_comm and cfg.positions:     # else only what on_position brings
            robot.core.team_pos = self.team_pos

    def _fail(self, rid):
        self.robots[rid].core.fail()

    def _repair(self, rid):
        self.robots[rid].core.repair()

    def comm_counters(self):
        """Every robot's receiver counters (agent_faults.COUNTER_KEYS)."""
        return {r.id: r.core.comm_counters() for r in self.robots if r.core is not None}

    def _write_scenario(self):
        write_scenario(self.prefix, self.cfg.comm, self.cfg.attrition, self.schedule_failures,
                       self.monitor.failures, self.comm_counters(), seed=self.cfg.seed,
                       mode="graph", occupancy=self.occupancy)

    def _timeresults(self):
        if self.writer:
            self.writer.time_row(self.monitor.stats(self.t))
        self.schedule(self.t + TIMERESULTS_PERIOD, self._timeresults)

    # -- run --------------------------------------------------------------------------------
    def run(self, write=True) -> Stats:
        """Simulate until the duration or cycle limit; write the four files if ``write``.
        Returns the final statistics. Raises :class:`NoSpaceError` (after recording what it
        could, status ABORTED) if the results' file system is full."""
        self.wall0 = time.monotonic()
        self.writer = None
        self.no_space = None
        stats = None
        try:
            if write:
                self._open_results()
            stats = self._simulate()
        except OSError as e:
            if not is_no_space(e):
                raise
            self._record_no_space(e)
        finally:
            if self.writer:
                self._close_results()
        if self.no_space:
            raise self.no_space
        return stats

    def _open_results(self):
        cfg = self.cfg
        if self.prefix is None:
            self.prefix = claim_prefix(default_prefix(cfg.results_dir, self.map_name,
                                                      cfg.robots, cfg.alg))
        self.writer = ResultWriter(self.prefix, RunInfo(
            self.map_name, cfg.robots, cfg.initpos, cfg.gwait, cfg.comm_delay, "graph",
            cfg.alg, "", hostname(), os.path.basename(self.prefix)),
            flush_every=WRITE_FLUSH_EVERY)
        write_start_poses(self.prefix + "_start_poses.txt",
                          [tuple(self.g.pos[v]) for v in self.start_vertices], self.g,
                          initpos_label(cfg.initpos, cfg.seed))
        with open(self.prefix + "_config.yaml", "w", encoding="utf-8") as f:
            f.write(config_yaml(cfg, self.start_vertices))

    def _simulate(self) -> Stats:
        self.begin()
        self.advance()
        return self.finish()

    def begin(self):
        """Start a run without writing files (what :meth:`run` does first): build the cores,
        GO at t = 0, schedule the timers and failures. Then :meth:`advance`, :meth:`finish`."""
        cfg = self.cfg
        for r in self.robots:
            self._make_core(r)
        # every navigation server is up at once; the monitor sees N announcements: GO
        self.monitor.start(0.0)
        for r in self.robots:
            r.core.ready()
        for r in self.robots:
            r.core.on_results([MONITOR_ID, MSG_INIT, GO])
        self.schedule(TIMERESULTS_PERIOD, self._timeresults)
        for f in self.schedule_failures:     # sim seconds after GO (t = 0)
            self.schedule(f.t, lambda k=f.robot: self._fail(k))
            if f.back is not None:
                self.schedule(f.back, lambda k=f.robot: self._repair(k))
        self.end = cfg.duration if cfg.duration > 0 else float("inf")
        self.termination = "TIMEOUT"

    def advance(self, stop: Optional[Callable[[], bool]] = None) -> bool:
        """Run the events in order until the duration or cycle limit (returns True: the run
        is over), or until ``stop()`` is true after an event (returns False; call again to
        go on: the same events in the same order as one uninterrupted call)."""
        cfg = self.cfg
        end = self.end
        events = self._events
        while True:
            tick_t = self.next_tick_time()   # ticks run after same-time events
            if events and events[0][0] <= tick_t:
                t, _, fn = heapq.heappop(events)
            elif tick_t < math.inf:
                t, fn = tick_t, self.run_tick
            else:
                break
            if t > end:
                break
            self.t = t
            fn()
            if cfg.cycles and self.monitor.cycles >= cfg.cycles:
                self.termination = "CYCLES"
                break
            if stop is not None and stop():
                return False
        if self.termination == "TIMEOUT" and end < float("inf"):
            self.t = end
        return True

    def finish(self) -> Stats:
        """The final statistics (and info.csv when writing) of a run :meth:`advance` ended."""
        stats = self.monitor.stats(self.t)
        if self.writer:
            core = self.robots[0].core
            self.writer.info.algorithm_params = core.strategy.algorithm_params if core else ""
            self.writer.write_info(stats, time.monotonic() - self.wall0, self.termination)
        return stats

    def _record_no_space(self, e):
        """Keep the first full-disk error (as a :class:`NoSpaceError`); the run is ABORTED."""
        if self.no_space is None:
            self.no_space = NoSpaceError(e.filename or f"{self.prefix}_*")

    def _guarded(self, fn, *args):
        """``fn(*args)``; a full disk is recorded instead of raised (True if it went well)."""
        try:
            fn(*args)
            return True
        except OSError as e:
            if not is_no_space(e):
                raise
            self._record_no_space(e)
            return False

    def _close_results(self):
        """Finish the result files whatever ended the run: info.csv (INTERRUPTED if the run
        did not reach its end), the scenario record, ``_run.yaml``; on a full disk, as much
        of them as fits, status ABORTED, and no temporary file left behind."""
        cfg, w = self.cfg, self.writer
        status = self.termination if w.info_written else run_status.INTERRUPTED
        if not w.info_written:     # interrupted: keep what was measured
            self._guarded(w.write_info, self.monitor.stats(self.t),
                          time.monotonic() - self.wall0, status)
        self._guarded(w.close)
        if self.scenario:
            self._guarded(self._write_scenario)
        if self.no_space:
            status = run_status.ABORTED
            self._guarded(run_status.set_info_status, self.prefix, status)
        reason = str(self.no_space) if self.no_space else {
            run_status.TIMEOUT: f"the duration of {cfg.duration:g} sim s was reached",
            run_status.CYCLES: f"{cfg.cycles} complete patrol cycles done",
            run_status.INTERRUPTED: "interrupted before the end"}.get(status, "")
        self._guarded(run_status.write_run_yaml, self.prefix, {
            "status": status, "reason": reason, "culprit": None, "robots": [],
            "signal": None, "sim_time": round(self.t, 1),
            "wall_time": round(time.monotonic() - self.wall0, 1),
            "longest_silence": [round(x, 1) for x in self.monitor.silences(self.t)],
            "exit_code": run_status.exit_code_for(status), "written_by": "graph_sim"})


def run_graph_experiment(cfg: GraphSimConfig, write=True, log=None):
    """Convenience: build and run; returns (stats, prefix or None)."""
    sim = GraphSimulator(cfg, log=log)
    stats = sim.run(write=write)
    return stats, sim.prefix
