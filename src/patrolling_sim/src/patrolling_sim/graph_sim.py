"""Graph-level discrete-event simulator: run a patrolling experiment in seconds, no ROS.

Robots are points that travel along shortest paths of the patrol graph at a constant speed.
Everything else is the real thing: the same strategy classes as the ROS PatrolAgent (through
the same :class:`~patrolling_sim.algorithms.base.Driver` protocol), the same monitor metrics
(:class:`~patrolling_sim.monitor_core.MonitorCore`) and the same result files
(:class:`~patrolling_sim.results.ResultWriter`, nav_module ``graph``), so graph-mode results
load in the report next to ROS runs.

Timeline of one robot, mirroring the agent node: GO at t = 0; after a random start delay
U(0, 1) s it reports its start vertex, decides, and travels; on reaching its goal it waits
``goal_wait`` s, then the strategy's ``on_arrival`` runs, the visit is reported and the next
goal chosen. Algorithm messages reach the other robots after ``comm_delay`` s, each dropped
with probability ``loss`` (one seeded generator). Interference (robots physically blocking
each other) is not modelled in this mode: the interference count is 0.

Deterministic: the same inputs and seed give the same files (apart from wall-clock fields).
"""
import heapq
import itertools
import os
import random
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

from . import paths
from .algorithms import REGISTRY, create
from .algorithms.base import Driver, StrategyContext
from .errors import PatrolInputError
from .graph import PatrolGraph
from .monitor_core import MonitorCore, Stats
from .results import ResultWriter, RunInfo, default_prefix, hostname, timestamp

TIMERESULTS_PERIOD = 900.0
#: shortest trip (s): a goal on the robot's own vertex still takes one navigation cycle, so
#: simulated time always advances between two decisions of a robot
MIN_TRIP = 0.5


@dataclass
class GraphSimConfig:
    """Inputs of one graph-mode run (defaults as the ROS runner's)."""
    map: str = "grid"
    robots: int = 1
    alg: str = "CR"
    duration: float = 3600.0        # sim seconds after GO; 0 = until `cycles`
    cycles: int = 0                 # stop after this many complete patrol cycles; 0 = off
    seed: int = 0
    speed: float = 1.0              # m/s along graph edges
    gwait: float = 0.0
    comm_delay: float = 0.0
    loss: float = 0.0
    initpos: str = "default"
    results_dir: str = "results"
    params: dict = field(default_factory=dict)

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
        paths.map_files(self.map)        # raises a one-line error for an unknown map
        return self


class _Robot:
    def __init__(self, rid):
        self.id = rid
        self.strategy = None
        self.vertex = None          # last vertex reached (or passed through on a redirect)
        self.goal = None
        self.path = []              # vertices of the current trip
        self.cum = []               # cumulative metres along path
        self.depart = 0.0
        self.trip = 0               # token: invalidates an arrival event after a redirect


class _SimDriver(Driver):
    def __init__(self, sim, robot):
        self.sim, self.robot = sim, robot

    def now(self):
        return self.sim.t

    def send(self, data):
        self.sim.broadcast(self.robot.id, list(data))

    def call_later(self, delay, fn):
        self.sim.schedule(self.sim.t + max(0.0, delay), fn)

    def redirect(self, vertex):
        self.sim.redirect(self.robot, vertex)


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
        self.rng = random.Random(cfg.seed)
        self.msg_rng = random.Random(cfg.seed * 7919 + 1)
        if start_vertices is None:
            start_vertices = self._start_vertices()
        if len(start_vertices) != cfg.robots:
            raise PatrolInputError(f"need {cfg.robots} start vertices, got {len(start_vertices)}")
        self.start_vertices = list(start_vertices)
        self.t = 0.0
        self._events = []
        self._seq = itertools.count()
        self.monitor = MonitorCore(self.g.n, cfg.robots)
        self.robots = [_Robot(i) for i in range(cfg.robots)]
        self.prefix = prefix
        self.log = log or (lambda s: None)
        self.messages_sent = 0
        self.messages_lost = 0
        self.termination = None

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

    # -- event queue ------------------------------------------------------------------------
    def schedule(self, t, fn):
        heapq.heappush(self._events, (t, next(self._seq), fn))

    def broadcast(self, sender, data):
        self.messages_sent += 1
        if self.cfg.loss > 0 and self.msg_rng.random() < self.cfg.loss:
            self.messages_lost += 1
            return
        t = self.t + self.cfg.comm_delay
        for r in self.robots:
            if r.id != sender and r.strategy is not None:
                self.schedule(t, lambda r=r: r.strategy.on_message(data, self.t))

    # -- motion -----------------------------------------------------------------------------
    def _travel(self, robot, origin, goal, t0):
        robot.goal = goal
        robot.trip += 1
        robot.path = self.g.path(origin, goal) or [origin]
        res = self.g.resolution
        cum = [0.0]
        for a, b in zip(robot.path, robot.path[1:]):
            cum.append(cum[-1] + self.g.arc_cost(a, b) * res)
        robot.cum = cum
        robot.depart = t0
        trip = robot.trip
        self.schedule(t0 + max(MIN_TRIP, cum[-1] / self.cfg.speed),
                      lambda: self._arrived(robot, trip))

    def redirect(self, robot, vertex):
        """Head to ``vertex`` from the next graph vertex on the current trip."""
        if robot.goal is None:
            return
        done = (self.t - robot.depart) * self.cfg.speed
        k = next((i for i, c in enumerate(robot.cum) if c >= done - 1e-9), len(robot.cum) - 1)
        via = robot.path[k]
        t_via = robot.depart + robot.cum[k] / self.cfg.speed
        robot.vertex = via
        self._travel(robot, via, vertex, max(self.t, t_via))

    def _arrived(self, robot, trip):
        if trip != robot.trip:
            return
        v = robot.goal
        robot.vertex = v
        robot.goal = None                       # waiting at the goal: nothing to redirect
        self.schedule(self.t + self.cfg.gwait, lambda: self._complete(robot, v))

    def _complete(self, robot, v):
        s = robot.strategy
        s.on_arrival(v, self.t)
        self._report(robot.id, v)
        nxt = s.next_vertex(self.t)
        self._travel(robot, v, nxt, self.t)

    # -- monitor ----------------------------------------------------------------------------
    def _report(self, rid, v):
        r = self.monitor.visit(rid, v, self.t)
        if r is None:
            return
        if r.idleness is not None and self.writer:
            self.writer.idleness_row(self.t, rid, v, r.idleness, self.monitor.interferences)
        if r.new_cycle:
            if self.writer:
                self.writer.cycle_block(self.monitor.stats(self.t), time.monotonic() - self.wall0)
            self.log(f"t={self.t:.1f} s: patrol cycle {r.cycles} complete")

    def _start_robot(self, robot):
        sv = self.start_vertices[robot.id]
        x, y = self.g.pos[sv]
        params = dict(self.cfg.params)
        params.setdefault("start_vertices", self.start_vertices)
        ctx = StrategyContext(self.g, robot.id, self.cfg.robots, self.map_name,
                              random.Random(self.cfg.seed * 1000 + robot.id + 1),
                              _SimDriver(self, robot), params, (float(x), float(y)))
        robot.strategy = create(self.cfg.alg, ctx)
        robot.vertex = sv
        robot.strategy.start(sv, self.t)
        self._report(robot.id, sv)
        nxt = robot.strategy.next_vertex(self.t)
        self._travel(robot, sv, nxt, self.t)

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
            self.monitor.start(0.0)
            for r in self.robots:
                self.schedule(self.rng.uniform(0.0, 1.0), lambda r=r: self._start_robot(r))
            self.schedule(TIMERESULTS_PERIOD, self._timeresults)
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
                params = self.robots[0].strategy.algorithm_params if self.robots[0].strategy else ""
                self.writer.info.algorithm_params = params
                self.writer.write_info(stats, time.monotonic() - self.wall0, self.termination)
            return stats
        finally:
            if self.writer:
                if not self.writer.info_written:     # interrupted: keep what was measured
                    self.writer.write_info(self.monitor.stats(self.t),
                                           time.monotonic() - self.wall0, "ABORT")
                self.writer.close()


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
        ap.add_argument("--results-dir", default="results")
        ap.add_argument("--repeat", type=int, default=1,
                        help="run this many times with seeds seed, seed+1, ...")
        ap.add_argument("--quiet", action="store_true")
        a = ap.parse_args(args)
        setup_logging()
        if a.repeat < 1:
            ap.error(f"argument --repeat: must be >= 1, got {a.repeat}")
        for k in range(a.repeat):
            cfg = GraphSimConfig(map=a.map, robots=a.robots, alg=a.alg, duration=a.duration,
                                 cycles=a.cycles, seed=a.seed + k, speed=a.speed, gwait=a.gwait,
                                 comm_delay=a.comm_delay, loss=a.loss, initpos=a.initpos,
                                 results_dir=a.results_dir)
            t0 = time.monotonic()
            stats, prefix = run_graph_experiment(cfg, log=None if a.quiet else print)
            print(f"{cfg.alg} on {paths.map_name(cfg.map)} with {cfg.robots} robot(s), seed "
                  f"{cfg.seed}: {stats.elapsed:.0f} s simulated in {time.monotonic() - t0:.2f} s"
                  f" | avg idleness {stats.global_avg:.1f} s | max {stats.global_max:.1f} s | "
                  f"cycles {stats.cycles} | visits {stats.total_visits}")
            print(f"results: {prefix}_*")
        return 0
    return run_main(_main, "graph_sim.py", argv)
