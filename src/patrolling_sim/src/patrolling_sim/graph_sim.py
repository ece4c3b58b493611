"""Graph-level discrete-event simulator: run a patrolling experiment in seconds, no ROS.

Every robot is the same :class:`~patrolling_sim.agent_core.PatrolAgentCore` as in the ROS
PatrolAgent node (same strategies, same life cycle and order of events, see
``docs/protocol.md``), driven here by simulated time; the monitor metrics
(:class:`~patrolling_sim.monitor_core.MonitorCore`) and result files
(:class:`~patrolling_sim.results.ResultWriter`, nav_module ``graph``) are the ROS mode's, so
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
import bisect
import heapq
import itertools
import math
import os
import random
import signal
import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

from . import paths, run_status, validation
from .agent_core import (GO, INTERFERENCE_DIST, INTERFERENCE_PERIOD, MONITOR_ID, Effects,
                         build_agent)
from .algorithms import REGISTRY
from .algorithms.base import MSG_INIT, MSG_INTERFERENCE, MSG_TARGET_REACHED
from .errors import PatrolInputError
from .graph import PatrolGraph
from .monitor_core import MonitorCore, Stats
from .results import ResultWriter, RunInfo, default_prefix, hostname, timestamp

TIMERESULTS_PERIOD = 900.0
#: shortest trip (s): a goal on the robot's own vertex still takes one navigation cycle, so
#: simulated time always advances between two decisions of a robot
MIN_TRIP = 0.5
#: s between two navigation feedbacks (positions published, interference evaluated): the
#: move_base controller's 5 Hz
FEEDBACK_PERIOD = 0.2
TRAVEL_MODES = ("graph", "euclidean")


@dataclass
class GraphSimConfig:
    """Inputs of one graph-mode run (defaults as the ROS runner's)."""
    map: str = "grid"
    robots: int = 1
    alg: str = "CR"
    duration: float = 3600.0        # sim seconds after GO; 0 = until `cycles`
    cycles: int = 0                 # stop after this many complete patrol cycles; 0 = off
    seed: int = 0
    speed: float = 1.0              # m/s along graph edges (or straight lines)
    gwait: float = 0.0
    comm_delay: float = 0.0
    loss: float = 0.0
    initpos: str = "default"
    results_dir: str = "results"
    params: dict = field(default_factory=dict)
    goal_fail: float = 0.0          # probability that a navigation goal fails on the way
    interference: bool = True       # robots within 2 m interfere (the original's rule)
    travel: str = "graph"           # "graph": shortest graph path; "euclidean": straight line

    def validate(self):
        if self.alg not in REGISTRY:
            raise PatrolInputError(f"argument --alg: unknown algorithm '{self.alg}' (known: "
                                   f"{', '.join(sorted(REGISTRY))})")
        if self.robots < 1:
            raise PatrolInputError(f"argument --robots: team size must be >= 1, got {self.robots}")
        if self.duration < 0 or (self.duration == 0 and self.cycles <= 0):
            raise PatrolInputError("argument --duration: must be > 0 (or give --cycles)")
        if self.cycles < 0:
            raise PatrolInputError(f"argument --cycles: must be >= 0, got {self.cycles}")
        if self.speed <= 0:
            raise PatrolInputError(f"argument --speed: must be > 0, got {self.speed}")
        if self.gwait < 0:
            raise PatrolInputError(f"argument --gwait: must be >= 0, got {self.gwait}")
        if self.comm_delay < 0:
            raise PatrolInputError(f"argument --comm-delay: must be >= 0, got {self.comm_delay}")
        if not 0 <= self.loss < 1:
            raise PatrolInputError(f"argument --loss: must be in [0, 1), got {self.loss}")
        if not 0 <= self.goal_fail < 1:
            raise PatrolInputError(f"argument --goal-fail: must be in [0, 1), got {self.goal_fail}")
        if self.travel not in TRAVEL_MODES:
            raise PatrolInputError(f"argument --travel: must be one of {', '.join(TRAVEL_MODES)}"
                                   f", got '{self.travel}'")
        # the same one-line errors as the experiment runner (patrolling_sim.validation)
        validation.check_map_files(self.map)
        return self


class _Robot(Effects):
    """One robot's body in the graph world and the :class:`Effects` its core acts through.

    The body is a point: on vertex ``a`` (``loc = (a, a, 0)``), or a fraction ``f`` along the
    edge a->b (``loc = (a, b, f)``). A trip is a list of straight pieces
    ``(x0, y0, x1, y1, length_m, a, b, f0, f1)`` run at constant speed."""

    def __init__(self, sim, rid, start_vertex):
        self.sim = sim
        self.id = rid
        self.core = None
        self.loc = (start_vertex, start_vertex, 0.0)
        self.xy = tuple(float(c) for c in sim.g.pos[start_vertex])
        self.last_vertex = start_vertex       # last vertex reached (reachability of goals)
        self.goal = None
        self.pieces = None                    # active trip, None when standing still
        self.cum = None                       # cumulative length at the end of each piece
        self.depart = 0.0
        self.duration = 0.0
        self.seq = None                       # the core's sequence number of the trip
        self.token = 0                        # bumps on every stop: stale events ignored

    # -- Effects ------------------------------------------------------------------------------
    def now(self):
        return self.sim.t

    def publish(self, data):
        self.sim.publish(self.id, data)

    def call_later(self, delay, fn):
        self.sim.schedule(self.sim.t + delay, fn)

    def backup(self):
        """Nothing to do: the real manoeuvre moves a robot a few centimetres, a point robot
        on the graph stays where it failed (the core still spends the back-up time)."""

    def clear_costmaps(self):
        """Nothing to do: the graph world has no costmaps."""

    def cancel_goal(self):
        self._stop()

    def send_goal(self, vertex, seq):
        sim = self.sim
        self._stop()
        self.token += 1
        token = self.token
        self.goal, self.seq = vertex, seq
        pieces = self._route(vertex)
        if pieces is None:                     # the graph cannot reach it: navigation fails
            sim.schedule(sim.t, lambda: self._failed(token, seq))
            return
        cum, total = [], 0.0
        for p in pieces:
            total += p[4]
            cum.append(total)
        self.pieces, self.cum, self.depart = pieces, cum, sim.t
        self.duration = max(MIN_TRIP, total / sim.cfg.speed)
        sim.wake()
        if sim.cfg.goal_fail > 0 and sim.rng.random() < sim.cfg.goal_fail:
            sim.schedule(sim.t + sim.rng.random() * self.duration,
                         lambda: self._failed(token, seq))
        else:
            sim.schedule(sim.t + self.duration, lambda: self._arrived(token, seq))

    # -- motion -------------------------------------------------------------------------------
    def _route(self, goal):
        """Pieces from the current location to ``goal``; None if unreachable."""
        g = self.sim.g
        res = g.resolution
        gx, gy = (float(c) for c in g.pos[goal])
        if not math.isfinite(g.dist[self.last_vertex, goal]):
            return None
        if self.sim.cfg.travel == "euclidean":
            x, y = self.xy
            return [(x, y, gx, gy, math.hypot(gx - x, gy - y), None, None, 0.0, 0.0)]
        a, b, f = self.loc
        if a != b and 0.0 < f < 1.0:
            # mid-edge (after a stop): leave by whichever end of the edge is shorter overall
            length = g.arc_cost(a, b) * res
            x, y = self.xy
            via_a = f * length + g.dist[a, goal] * res
            via_b = (1.0 - f) * length + g.dist[b, goal] * res
            if not (math.isfinite(via_a) or math.isfinite(via_b)):
                return None
            if via_b <= via_a:
                end, first = b, (x, y, *g.pos[b], (1.0 - f) * length, a, b, f, 1.0)
            else:
                end, first = a, (x, y, *g.pos[a], f * length, a, b, f, 0.0)
            return [first] + self._edge_pieces(g.path(end, goal))
        start = b if (a != b and f >= 1.0) else a
        path = g.path(start, goal)
        return None if path is None else self._edge_pieces(path)

    def _edge_pieces(self, path):
        g = self.sim.g
        res = g.resolution
        out = []
        for u, w in zip(path, path[1:]):
            (x0, y0), (x1, y1) = g.pos[u], g.pos[w]
            out.append((float(x0), float(y0), float(x1), float(y1), g.arc_cost(u, w) * res,
                        u, w, 0.0, 1.0))
        return out

    def position(self, t):
        """(x, y, loc) at time ``t`` of the active trip."""
        total = self.cum[-1] if self.cum else 0.0
        if total <= 0.0:
            return self.xy[0], self.xy[1], self.loc
        s = min(total, max(0.0, (t - self.depart) / self.duration * total))
        k = min(bisect.bisect_left(self.cum, s), len(self.pieces) - 1)
        x0, y0, x1, y1, length, a, b, f0, f1 = self.pieces[k]
        into = s - (self.cum[k] - length)
        r = into / length if length > 0 else 1.0
        x, y = x0 + (x1 - x0) * r, y0 + (y1 - y0) * r
        loc = (a, b, f0 + (f1 - f0) * r) if a is not None else self.loc
        return x, y, loc

    def _stop(self):
        """Stand still where the robot is now; pending arrival/failure events go stale.
        The robot's last published position is where it stopped."""
        if self.pieces is None:
            return
        x, y, self.loc = self.position(self.sim.t)
        self.xy = (x, y)
        self.pieces = self.cum = None
        self.token += 1
        self.sim.stood(self)                       # last feedback: where it stopped

    def _arrived(self, token, seq):
        if token != self.token:
            return
        v = self.goal
        self.pieces = self.cum = None
        self.token += 1
        self.loc = (v, v, 0.0)
        self.xy = tuple(float(c) for c in self.sim.g.pos[v])
        self.sim.stood(self)                       # last feedback: on the vertex
        self.last_vertex = v
        self.core.on_goal_result(seq, True)

    def _failed(self, token, seq):
        if token != self.token:
            return
        self._stop()
        self.core.on_goal_result(seq, False)


class GraphSimulator:
    """One run. Use :meth:`run`; see the module docstring for the model."""

    def __init__(self, cfg: GraphSimConfig, start_vertices: Optional[Sequence[int]] = None,
                 pgraph: Optional[PatrolGraph] = None, prefix: Optional[str] = None,
                 log: Optional[Callable[[str], None]] = None):
        self.cfg = cfg.validate()
        self.map_name = paths.map_name(cfg.map)
        if pgraph is None:
            pgraph = PatrolGraph.load(paths.map_files(cfg.map)[1])
        self.g = pgraph
        self.rng = random.Random(cfg.seed)     # the world's own draws (goal failures)
        if start_vertices is None:
            start_vertices = self._start_vertices()
        if len(start_vertices) != cfg.robots:
            raise PatrolInputError(f"need {cfg.robots} start vertices, got {len(start_vertices)}")
        self.start_vertices = list(start_vertices)
        self.t = 0.0
        self._events = []
        self._seq = itertools.count()
        self.monitor = MonitorCore(self.g.n, cfg.robots)
        self.robots = [_Robot(self, i, v) for i, v in enumerate(self.start_vertices)]
        #: positions robots have published while moving (shared by all cores)
        self.team_pos = {}
        #: skip feedback work that cannot find an interference (same results, faster)
        self.skip_idle_ticks = True
        self._cur = [r.xy for r in self.robots]      # where each robot is (at the last tick)
        self._tick = math.inf
        self._bound_wait = 0                          # ticks until the skip bound is computed
        self._bound_backoff = 1
        self.prefix = prefix
        self.log = log or (lambda s: None)
        self.termination = None
        self.writer = None

    def _start_vertices(self):
        from .initial_poses import load_initial_poses, start_positions
        from .mapio import load_map
        yaml_path, _ = paths.map_files(self.cfg.map)
        occ = load_map(yaml_path)
        table_path = paths.initial_poses_file()
        pos, _ = start_positions(self.map_name, self.cfg.robots, self.g, occ,
                                 self.cfg.initpos, load_initial_poses(table_path), table_path,
                                 alg=self.cfg.alg)
        return [self.g.nearest_vertex(x, y) for x, y in pos]

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
        elif kind == MSG_INTERFERENCE:
            self.monitor.interference(sender, self.t)
        elif kind != MSG_INIT:
            for r in self.robots:
                if r.id != sender:
                    self.schedule(self.t, lambda r=r: r.core.on_results(data))

    def stood(self, robot):
        """``robot`` stopped at ``robot.xy``: that is its last published position."""
        self.team_pos[robot.id] = self._cur[robot.id] = robot.xy

    def wake(self):
        """A robot started a trip: the next feedback tick must not be later than the next
        one of the FEEDBACK_PERIOD lattice."""
        if not self.cfg.interference:
            return
        k = int(self.t / FEEDBACK_PERIOD) + 1
        if k < self._tick:
            self._tick = k
            self.schedule(k * FEEDBACK_PERIOD, lambda: self._feedback(k))

    def _feedback(self, k):
        """Navigation feedback at tick ``k`` (time k * FEEDBACK_PERIOD, move_base's 5 Hz):
        every moving robot publishes its position, then evaluates interference.

        Only the work that can find something is done: a robot in its 10 s quiet period,
        or farther than INTERFERENCE_DIST from every published position of a lower id, would
        find nothing, so its core is not asked; and since no robot moves faster than
        ``speed``, no pair with a moving robot comes within INTERFERENCE_DIST for
        (d - INTERFERENCE_DIST) / (closing speed) s, so those ticks are skipped (a robot
        starting a trip wakes the next tick). Results are the same as with every tick
        simulated and every core asked (``skip_idle_ticks = False``, checked by a test)."""
        if k != self._tick:
            return                               # superseded by an earlier wake
        t = self.t
        cur, team = self._cur, self.team_pos
        moving = []
        for r in self.robots:
            if r.pieces is not None:
                x, y, _ = r.position(t)
                cur[r.id] = team[r.id] = (x, y)
                moving.append(r)
        lazy = self.skip_idle_ticks
        d2max = INTERFERENCE_DIST * INTERFERENCE_DIST
        for r in moving:
            core = r.core
            x, y = cur[r.id]
            if lazy:
                if t - core.last_interference < INTERFERENCE_PERIOD:
                    continue
                for j in range(r.id):
                    p = team.get(j)
                    if p is not None and (p[0] - x) ** 2 + (p[1] - y) ** 2 <= d2max:
                        break
                else:
                    continue
            core.on_feedback(r.seq, x, y)
        moving = [r.id for r in moving if r.pieces is not None]
        if not moving:
            self._tick = math.inf                # nobody moves: the next trip wakes us
            return
        skip = 1
        self._bound_wait -= 1
        if lazy and self._bound_wait <= 0:
            # closest (moving, moving) and (moving, standing) pairs
            is_moving = [r.pieces is not None for r in self.robots]
            mm = ms = math.inf
            for i in moving:
                x, y = cur[i]
                for j, (qx, qy) in enumerate(cur):
                    if j != i:
                        d2 = (qx - x) ** 2 + (qy - y) ** 2
                        if is_moving[j]:
                            if d2 < mm:
                                mm = d2
                        elif d2 < ms:
                            ms = d2
            v = self.cfg.speed
            horizon = min((math.sqrt(mm) - INTERFERENCE_DIST) / (2 * v),
                          (math.sqrt(ms) - INTERFERENCE_DIST) / v)
            if horizon == math.inf:              # a team of one
                self._tick = math.inf
                return
            skip = max(1, int(horizon / FEEDBACK_PERIOD))
            # robots close together: the bound will not help for a while, ask less often
            self._bound_backoff = 1 if skip > 1 else min(16, 2 * self._bound_backoff)
            self._bound_wait = self._bound_backoff
        self._tick = k + skip
        self.schedule(self._tick * FEEDBACK_PERIOD, lambda: self._feedback(k + skip))

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
        params = dict(cfg.params)
        params.setdefault("start_vertices", self.start_vertices)
        robot.core = build_agent(robot, self.g, robot.id, cfg.robots, self.map_name, cfg.alg,
                                 sv, robot.xy, seed=cfg.seed * 1000 + robot.id + 1,
                                 params=params, goal_wait=cfg.gwait,
                                 comm_delay=cfg.comm_delay, loss=cfg.loss)
        robot.core.team_pos = self.team_pos

    def _timeresults(self):
        if self.writer:
            self.writer.time_row(self.monitor.stats(self.t))
        self.schedule(self.t + TIMERESULTS_PERIOD, self._timeresults)

    # -- run --------------------------------------------------------------------------------
    def run(self, write=True) -> Stats:
        """Simulate until the duration or cycle limit; write the four files if ``write``.
        Returns the final statistics."""
        cfg = self.cfg
        self.wall0 = time.monotonic()
        self.writer = None
        if write:
            if self.prefix is None:
                self.prefix = claim_prefix(default_prefix(cfg.results_dir, self.map_name,
                                                          cfg.robots, cfg.alg))
            self.writer = ResultWriter(self.prefix, RunInfo(
                self.map_name, cfg.robots, cfg.initpos, cfg.gwait, cfg.comm_delay, "graph",
                cfg.alg, "", hostname(), os.path.basename(self.prefix)))
            from .startpos import write_start_poses
            write_start_poses(self.prefix + "_start_poses.txt",
                              [tuple(self.g.pos[v]) for v in self.start_vertices], self.g,
                              f"--initpos {cfg.initpos}")
        try:
            for r in self.robots:
                self._make_core(r)
            # every navigation server is up at once; the monitor sees N announcements: GO
            self.monitor.start(0.0)
            for r in self.robots:
                r.core.ready()
            for r in self.robots:
                r.core.on_results([MONITOR_ID, MSG_INIT, GO])
            self.schedule(TIMERESULTS_PERIOD, self._timeresults)
            self._tick = math.inf                # feedback ticks start with the first trip
            end = cfg.duration if cfg.duration > 0 else float("inf")
            self.termination = "TIMEOUT"
            while self._events:
                t, _, fn = heapq.heappop(self._events)
                if t > end:
                    break
                self.t = t
                fn()
                if cfg.cycles and self.monitor.cycles >= cfg.cycles:
                    self.termination = "CYCLES"
                    break
            if self.termination == "TIMEOUT" and end < float("inf"):
                self.t = end
            stats = self.monitor.stats(self.t)
            if self.writer:
                core = self.robots[0].core
                self.writer.info.algorithm_params = core.strategy.algorithm_params if core else ""
                self.writer.write_info(stats, time.monotonic() - self.wall0, self.termination)
            return stats
        finally:
            if self.writer:
                status = self.termination if self.writer.info_written else \
                    run_status.INTERRUPTED
                if not self.writer.info_written:     # interrupted: keep what was measured
                    self.writer.write_info(self.monitor.stats(self.t),
                                           time.monotonic() - self.wall0, status)
                self.writer.close()
                run_status.write_run_yaml(self.prefix, {
                    "status": status, "reason": {
                        run_status.TIMEOUT: f"the duration of {cfg.duration:g} sim s was "
                                            f"reached",
                        run_status.CYCLES: f"{cfg.cycles} complete patrol cycles done",
                        run_status.INTERRUPTED: "interrupted before the end"}.get(status, ""),
                    "culprit": None, "robots": [], "signal": None,
                    "sim_time": round(self.t, 1),
                    "wall_time": round(time.monotonic() - self.wall0, 1),
                    "exit_code": run_status.exit_code_for(status), "written_by": "graph_sim"})


def claim_prefix(prefix: str) -> str:
    """``prefix`` or ``prefix_k``: the first whose idleness file can be created exclusively
    (safe when several runs start in the same second)."""
    os.makedirs(os.path.dirname(prefix) or ".", exist_ok=True)
    for k in range(1000):
        p = prefix if k == 0 else f"{prefix}_{k}"
        try:
            os.close(os.open(p + "_idleness.csv", os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
            return p
        except FileExistsError:
            continue
    raise PatrolInputError(f"argument --results-dir: cannot create a unique run prefix for {prefix}")


def run_graph_experiment(cfg: GraphSimConfig, write=True, log=None):
    """Convenience: build and run; returns (stats, prefix or None)."""
    sim = GraphSimulator(cfg, log=log)
    stats = sim.run(write=write)
    return stats, sim.prefix


def main(argv=None):
    from .cli import CliParser, run_main, setup_logging

    def _main(args):
        ap = CliParser(prog="graph_sim.py", description=(
            "Run a patrolling experiment at graph level (no ROS): robots travel along the "
            "patrol graph at constant speed; same algorithms, metrics and result files as "
            "the ROS mode."))
        ap.add_argument("--map", default="grid", help="map name or path to its yaml/.graph")
        ap.add_argument("--robots", type=int, default=1, help="team size N")
        ap.add_argument("--alg", default="CR", help="algorithm: " + ", ".join(sorted(REGISTRY)))
        ap.add_argument("--duration", type=float, default=3600.0,
                        help="simulated seconds after GO (0: run until --cycles)")
        ap.add_argument("--cycles", type=int, default=0,
                        help="stop after this many complete patrol cycles (0: off)")
        ap.add_argument("--seed", type=int, default=0)
        ap.add_argument("--speed", type=float, default=1.0, help="robot speed (m/s)")
        ap.add_argument("--gwait", type=float, default=0.0, help="goal wait (s)")
        ap.add_argument("--comm-delay", type=float, default=0.0, help="message delay (s)")
        ap.add_argument("--loss", type=float, default=0.0, help="message loss rate [0, 1)")
        ap.add_argument("--initpos", default="default", help="initial poses variant")
        ap.add_argument("--goal-fail", type=float, default=0.0,
                        help="probability that a navigation goal fails on the way [0, 1)")
        ap.add_argument("--interference", choices=("on", "off"), default="on",
                        help="robots closer than 2 m interfere (default on)")
        ap.add_argument("--travel", choices=TRAVEL_MODES, default="graph",
                        help="graph: along shortest graph paths; euclidean: straight line "
                             "to the goal vertex (default graph)")
        ap.add_argument("--results-dir", default="results")
        ap.add_argument("--repeat", type=int, default=1,
                        help="run this many times with seeds seed, seed+1, ...")
        ap.add_argument("--quiet", action="store_true")
        a = ap.parse_args(args)
        setup_logging()
        got = []

        def on_term(signum, frame):     # SIGTERM ends the run as SIGINT does: files kept
            got.append(signum)
            raise KeyboardInterrupt
        signal.signal(signal.SIGTERM, on_term)
        if a.repeat < 1:
            ap.error(f"argument --repeat: must be >= 1, got {a.repeat}")
        first = GraphSimConfig(map=a.map, robots=a.robots, alg=a.alg, duration=a.duration,
                               cycles=a.cycles, seed=a.seed, speed=a.speed, gwait=a.gwait,
                               comm_delay=a.comm_delay, loss=a.loss, initpos=a.initpos,
                               results_dir=a.results_dir).validate()
        _, pgraph = validation.check_start_positions(first.map, first.robots, first.initpos,
                                                     alg=first.alg)
        warning = validation.team_size_warning(first.robots, pgraph.n, paths.map_name(a.map))
        if warning:
            print(warning, file=sys.stderr)
        validation.check_writable_dir(a.results_dir)
        for k in range(a.repeat):
            cfg = GraphSimConfig(map=a.map, robots=a.robots, alg=a.alg, duration=a.duration,
                                 cycles=a.cycles, seed=a.seed + k, speed=a.speed, gwait=a.gwait,
                                 comm_delay=a.comm_delay, loss=a.loss, initpos=a.initpos,
                                 results_dir=a.results_dir, goal_fail=a.goal_fail,
                                 interference=a.interference == "on", travel=a.travel)
            t0 = time.monotonic()
            sim = GraphSimulator(cfg, log=None if a.quiet else print)
            # a map that is not a shipped one is filed under a name that cannot collide
            # with a shipped map (its name + a hash of its files), as in the ROS runner
            label = validation.result_map_name(cfg.map)
            if label != sim.map_name:
                sim.prefix = claim_prefix(default_prefix(cfg.results_dir, label, cfg.robots,
                                                         cfg.alg))
            try:
                stats = sim.run()
            except KeyboardInterrupt:
                if sim.prefix:
                    sig = "SIGTERM" if got else "SIGINT"
                    rec = run_status.read_run_yaml(sim.prefix) or {}
                    rec.update(signal=sig, exit_code=run_status.exit_code_for(
                        run_status.INTERRUPTED, sig), reason=f"interrupted by {sig}")
                    run_status.write_run_yaml(sim.prefix, rec)
                    print(f"interrupted by {sig}; results: {sim.prefix}_*", file=sys.stderr)
                return run_status.exit_code_for(run_status.INTERRUPTED,
                                                "SIGTERM" if got else "SIGINT")
            prefix = sim.prefix
            if label != sim.map_name:
                run_status.set_info_field(prefix, 0, label)
            avg = "-" if stats.global_avg is None else f"{stats.global_avg:.1f} s"
            mx = "-" if stats.global_max is None else f"{stats.global_max:.1f} s"
            print(f"{cfg.alg} on {paths.map_name(cfg.map)} with {cfg.robots} robot(s), seed "
                  f"{cfg.seed}: {stats.elapsed:.0f} s simulated in {time.monotonic() - t0:.2f} s"
                  f" | avg idleness {avg} | max {mx} | "
                  f"cycles {stats.cycles} | visits {stats.total_visits}")
            print(f"results: {prefix}_*")
        return 0
    return run_main(_main, "graph_sim.py", argv)
