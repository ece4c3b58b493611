"""The monitor's measurements, as a pure state machine (docs/monitor.md).

Both the ROS ``monitor`` node and the graph-level simulator feed it the same events, so
results from the two modes are computed by one piece of code:

    core = MonitorCore(n_vertices=25, team_size=4)
    core.robot_ready(0) ... core.robot_ready(3)   # -> True when the team is complete
    core.start(now)                               # GO: time zero
    r = core.visit(robot, vertex, now)            # a TARGET_REACHED report [id,11,v]
    core.interference(robot, now)                 # an INTERFERENCE report [id,12]
    core.robot_failed(robot, now)                 # [id,13,0]; core.robot_repaired: [id,13,1]
    s = core.stats(now)                           # every metric (docs/monitor.md, "Metrics")

Definitions (the original's, without its bugs):

- visit counters start at -1, so a vertex's first visit (including the start-vertex report)
  yields no idleness sample; each later visit samples ``t - last_visit[v]``;
- complete patrol cycles = min over vertices of the counter (= minimum visit count - 1);
- global min/avg/SD/max over all samples; SD is the population SD; with no sample at all
  (no vertex visited twice) they are None, written as empty fields (not 0: a run without a
  measurement has no idleness, not an idleness of 0 s);
- node level: avg[v] = mean of v's samples (0 if none); worst = max avg[v]; graph avg, graph
  population SD and a true median of avg[v] over all vertices;
- interference rate = interferences after GO / elapsed sim time * 60 (per minute);
- total visits = sum of the -1-based counters (a never-visited vertex counts 0, not -1 as
  upstream); avg visits per node = total / V.
"""
import math
import statistics
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Set


@dataclass
class VisitResult:
    """What one visit report produced.

    Attributes:
        t: time since GO (s).
        idleness: the idleness sample (s), or None on the vertex's first visit.
        new_cycle: True if this visit completed a new patrol cycle.
        cycles: complete patrol cycles after this visit.
    """
    t: float
    idleness: Optional[float]
    new_cycle: bool
    cycles: int


@dataclass
class VertexStats:
    avg: float
    sd: float
    visits: int          # the -1-based counter (= number of samples once visited)


@dataclass
class Stats:
    """Every metric of docs/monitor.md ("Metrics") at one instant."""
    elapsed: float
    cycles: int
    n_samples: int
    global_min: Optional[float]     # None: no idleness sample
    global_avg: Optional[float]
    global_sd: Optional[float]
    global_max: Optional[float]
    worst_avg: float
    graph_avg: float
    graph_median: float
    graph_sd: float
    interferences: int
    interference_rate: float
    total_visits: int
    avg_visits_per_node: float
    per_vertex: List[VertexStats] = field(default_factory=list)


def population_sd(n: int, s1: float, s2: float) -> float:
    """Population SD from count, sum and sum of squares (0 for n < 1), clamped at 0."""
    if n < 1:
        return 0.0
    var = s2 / n - (s1 / n) ** 2
    return math.sqrt(var) if var > 0 else 0.0


class MonitorCore:
    """Monitor state for a graph of ``n_vertices`` and a team of ``team_size`` robots."""

    def __init__(self, n_vertices: int, team_size: int):
        if n_vertices < 1:
            raise ValueError("n_vertices must be >= 1")
        if team_size < 1:
            raise ValueError("team_size must be >= 1")
        self.n = n_vertices
        self.team_size = team_size
        self.ready: Set[int] = set()
        self.time_zero: Optional[float] = None
        self.visits = [-1] * n_vertices
        #: min(self.visits) and how many vertices have it, kept up to date by visit() (the
        #: cycle count is that minimum; recounting every vertex at each visit cost a few per
        #: cent of a graph-mode run)
        self._min_visits = -1
        self._at_min = n_vertices
        self.last_visit = [0.0] * n_vertices     # time since GO of the last visit
        self._vn = [0] * n_vertices              # per-vertex sample count
        self._vs1 = [0.0] * n_vertices
        self._vs2 = [0.0] * n_vertices
        self.n_samples = 0
        self._s1 = 0.0
        self._s2 = 0.0
        self.min_idl = 0.0
        self.max_idl = 0.0
        self.interferences = 0
        self.cycles = 0
        #: robot id -> time since GO of its last visit report (the FAIL rule, docs/monitor.md
        #: "Run statuses")
        self.last_report: Dict[int, float] = {}
        #: robot id -> its longest closed interval without a visit report (see silences())
        self._longest_silence: Dict[int, float] = {}
        #: visit reports from robot ids outside the team (see visit())
        self.foreign_reports = 0
        #: robots failed now (scenario failures, docs/scenarios.md): not a FAIL of the run
        self.dead_robots: Set[int] = set()
        #: every failure: [robot, t_fail, t_repair or None] (times since GO)
        self.failures: List[list] = []

    # -- handshake ----------------------------------------------------------------------
    def robot_ready(self, robot_id: int) -> bool:
        """Record ``[id,10,1]``. True exactly once: when this call completes the team."""
        if not 0 <= robot_id < self.team_size:
            return False
        before = len(self.ready)
        self.ready.add(robot_id)
        return before < self.team_size == len(self.ready)

    @property
    def started(self) -> bool:
        return self.time_zero is not None

    def start(self, now: float) -> None:
        """GO: ``now`` becomes time zero."""
        self.time_zero = float(now)
        self.last_report = {r: 0.0 for r in range(self.team_size)}
        self._longest_silence = {}

    def elapsed(self, now: float) -> float:
        return 0.0 if self.time_zero is None else float(now) - self.time_zero

    # -- events -------------------------------------------------------------------------
    def visit(self, robot_id: int, vertex: int, now: float) -> Optional[VisitResult]:
        """Record ``[id,11,v]`` at absolute time ``now``. Ignored (None) before GO or for a
        vertex id outside the graph. A report from a robot id outside the team counts in the
        idleness, as the original's monitor counts it, but not in the silence (FAIL) rule,
        which, as the original's, watches the team's ids only: such a sender that then went
        quiet must not end the run as a FAIL of a robot the run does not have
        (``foreign_reports`` counts these reports)."""
        if not self.started or not 0 <= vertex < self.n:
            return None
        t = self.elapsed(now)
        if 0 <= robot_id < self.team_size:
            self._end_silence(robot_id, t)
            self.last_report[robot_id] = t
        else:
            self.foreign_reports += 1
        if self.visits[vertex] == self._min_visits:
            self._at_min -= 1
            if self._at_min == 0:               # every vertex is above the old minimum
                self._min_visits += 1
                self._at_min = self.visits.count(self._min_visits) + 1   # + this vertex
        self.visits[vertex] += 1
        idl = None
        if self.visits[vertex] > 0:
            idl = t - self.last_visit[vertex]
            if self.n_samples == 0 or idl > self.max_idl:
                self.max_idl = idl
            if self.n_samples == 0 or idl < self.min_idl or self.min_idl < 0.1:
                self.min_idl = idl
            self.n_samples += 1
            self._s1 += idl
            self._s2 += idl * idl
            self._vn[vertex] += 1
            self._vs1[vertex] += idl
            self._vs2[vertex] += idl * idl
        self.last_visit[vertex] = t
        cycles = max(0, self._min_visits)
        new_cycle = cycles > self.cycles
        self.cycles = cycles
        return VisitResult(t, idl, new_cycle, cycles)

    def interference(self, robot_id: int, now: float) -> None:
        """Record ``[id,12]`` (ignored before GO)."""
        if self.started:
            self.interferences += 1

    def robot_failed(self, robot_id: int, now: float) -> None:
        """Record ``[id,13,0]``: a scheduled failure. Idleness keeps being measured over every
        vertex; the robot is exempt from the silence (FAIL) rule while it is down."""
        if not self.started or robot_id in self.dead_robots:
            return
        self._end_silence(robot_id, self.elapsed(now))
        self.dead_robots.add(robot_id)
        self.failures.append([robot_id, self.elapsed(now), None])

    def robot_repaired(self, robot_id: int, now: float) -> None:
        """Record ``[id,13,1]``: the robot is back; its silence clock restarts now."""
        if robot_id not in self.dead_robots:
            return
        self.dead_robots.discard(robot_id)
        t = self.elapsed(now)
        for f in reversed(self.failures):
            if f[0] == robot_id and f[2] is None:
                f[2] = t
                break
        self.last_report[robot_id] = t

    def silent_robots(self, now: float, timeout: float) -> List[int]:
        """Robots not failed whose last visit report is older than ``timeout`` s (the FAIL
        rule, docs/monitor.md "Run statuses"); failed robots are never listed."""
        t = self.elapsed(now)
        return sorted(r for r, last in self.last_report.items()
                      if r not in self.dead_robots and t - last > timeout)

    def _end_silence(self, robot_id: int, t: float) -> None:
        """A robot's silence ends at ``t`` (a visit report, or its failure: a failed robot's
        down time is not silence)."""
        if robot_id in self.dead_robots or robot_id not in self.last_report:
            return
        gap = t - self.last_report[robot_id]
        if gap > self._longest_silence.get(robot_id, 0.0):
            self._longest_silence[robot_id] = gap

    def silences(self, now: float) -> List[float]:
        """For each robot id (0 .. team_size - 1), the longest time since GO in which it sent
        no visit report: between two reports, from GO to its first, or from its last to
        ``now`` (a scheduled failure's down time excluded). [] before GO. Recorded in
        ``_run.yaml`` (``longest_silence``, docs/monitor.md), so that a robot that stopped
        for a while shows in a run that still ended normally."""
        if not self.started:
            return []
        t = self.elapsed(now)
        out = []
        for r in range(self.team_size):
            s = self._longest_silence.get(r, 0.0)
            if r not in self.dead_robots:
                s = max(s, t - self.last_report.get(r, 0.0))
            out.append(s)
        return out

    # -- metrics ------------------------------------------------------------------------
    def current_idleness(self, now: float) -> List[float]:
        """Instantaneous idleness of every vertex (time since its last visit, or since GO)."""
        t = self.elapsed(now)
        return [max(0.0, t - lv) for lv in self.last_visit]

    def stats(self, now: float) -> Stats:
        elapsed = self.elapsed(now)
        per = []
        for v in range(self.n):
            k = self._vn[v]
            avg = self._vs1[v] / k if k else 0.0
            per.append(VertexStats(avg, population_sd(k, self._vs1[v], self._vs2[v]),
                                   self.visits[v]))
        avgs = [p.avg for p in per]
        g_avg = sum(avgs) / self.n
        total = sum(max(c, 0) for c in self.visits)
        return Stats(
            elapsed=elapsed,
            cycles=self.cycles,
            n_samples=self.n_samples,
            global_min=self.min_idl if self.n_samples else None,
            global_avg=self._s1 / self.n_samples if self.n_samples else None,
            global_sd=population_sd(self.n_samples, self._s1, self._s2)
            if self.n_samples else None,
            global_max=self.max_idl if self.n_samples else None,
            worst_avg=max(avgs),
            graph_avg=g_avg,
            graph_median=float(statistics.median(avgs)),
            graph_sd=math.sqrt(max(0.0, sum((a - g_avg) ** 2 for a in avgs) / self.n)),
            interferences=self.interferences,
            interference_rate=self.interferences / elapsed * 60.0 if elapsed > 0 else 0.0,
            total_visits=total,
            avg_visits_per_node=total / self.n,
            per_vertex=per,
        )
