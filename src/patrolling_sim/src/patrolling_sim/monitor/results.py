"""Result files, in the original monitor's formats (docs/monitor.md, "Result files").

One experiment writes four files sharing a *prefix*
``<results_dir>/<map>_<N>/<ALG>/<host>/<YYYYMMDD_HHMMSS>``:

- ``<prefix>_idleness.csv``    one row per idleness sample (absolute sim time),
- ``<prefix>_timeresults.csv`` one row every 900 s of sim time,
- ``<prefix>_results.txt``     one block per completed patrol cycle,
- ``<prefix>_info.csv``        one line of 22 fields, written when the run ends.

Every write is flushed (by default at once; ``flush_every`` seconds of wall time apart in
graph mode, whose ``finally`` closes the files on any exception or Ctrl-C), so a run that is
killed keeps everything measured so far. The ROS monitor and the graph-level simulator both
use :class:`ResultWriter`.
"""
import datetime
import os
import socket
import time
from dataclasses import dataclass
from typing import List, Optional

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import write_atomic
from patrolling_sim.monitor.core import Stats

IDLENESS_HEADER = "Time;Robot;Node;Idleness;Interferences"
#: header of ``<prefix>_visits.csv`` (not a file of the original's)
VISITS_HEADER = "Time;Robot;Node"
TIMERESULTS_HEADER = "Time;Idleness min;Idleness avg;Idleness stddev;Idleness max;Interferences"
#: statuses of field 14 (patrolling_sim.monitor.run_status explains each)
TERMINATIONS = ("TIMEOUT", "CYCLES", "STOPPED", "FAIL", "ABORTED", "CRASHED", "INTERRUPTED")
#: field names of the 22-field info.csv line, in order
INFO_FIELDS = ("map", "team_size", "initial_positions", "goal_wait", "comm_delay",
               "nav_module", "algorithm", "algorithm_params", "hostname", "date",
               "sim_duration", "real_duration", "interferences", "termination", "idl_min",
               "idl_avg", "idl_stddev", "idl_max", "interference_rate", "total_visits",
               "avg_visits_per_node", "complete_cycles")


def hostname() -> str:
    try:
        return socket.gethostname() or "default"
    except OSError:
        return "default"


def timestamp(when: Optional[datetime.datetime] = None) -> str:
    """Local wall time as ``YYYYMMDD_HHMMSS`` (the original's run name)."""
    return (when or datetime.datetime.now()).strftime("%Y%m%d_%H%M%S")


def default_prefix(results_dir: str, map_name: str, team_size: int, alg: str,
                   host: Optional[str] = None, stamp: Optional[str] = None) -> str:
    """``<results_dir>/<map>_<N>/<ALG>/<host>/<stamp>`` (folders not created)."""
    return os.path.join(results_dir, f"{map_name}_{team_size}", alg, host or hostname(),
                        stamp or timestamp())


def claim_prefix(prefix: str, marker: str = "_idleness.csv", content: str = "") -> str:
    """``prefix`` or ``prefix_k``: the first for which ``<prefix>[_k]<marker>`` can be
    created exclusively (safe when several runs start in the same second); that file is
    created with ``content``. Parent folders are created. The one prefix claim of the
    runner (marker ``_config.yaml``, the configuration) and of graph mode."""
    os.makedirs(os.path.dirname(prefix) or ".", exist_ok=True)
    for k in range(1000):
        p = prefix if k == 0 else f"{prefix}_{k}"
        try:
            fd = os.open(p + marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            continue
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(content)
        return p
    raise PatrolInputError(f"argument --results-dir: cannot create a unique run prefix "
                           f"for {prefix}")


@dataclass
class RunInfo:
    """The descriptive part of info.csv (fields 1-10)."""
    map: str
    team_size: int
    initial_positions: str = "default"
    goal_wait: float = 0.0
    comm_delay: float = 0.0
    nav_module: str = "ros"
    alg: str = ""
    algorithm_params: str = ""
    hostname: str = ""
    date: str = ""


def fmt1(x) -> str:
    """``%.1f`` of a metric, or an empty field when there is no value (no sample)."""
    return "" if x is None else f"{x:.1f}"


def info_line(info: RunInfo, stats: Stats, real_elapsed: float, termination: str) -> str:
    """The single info.csv line (no trailing newline)."""
    f = [info.map, str(info.team_size), info.initial_positions, f"{info.goal_wait:.1f}",
         f"{info.comm_delay:.2f}", info.nav_module, info.alg, info.algorithm_params,
         info.hostname or hostname(), info.date, f"{stats.elapsed:.1f}", f"{real_elapsed:.1f}",
         str(stats.interferences), termination, fmt1(stats.global_min),
         fmt1(stats.global_avg), fmt1(stats.global_sd), fmt1(stats.global_max),
         f"{stats.interference_rate:.2f}", str(stats.total_visits),
         f"{stats.avg_visits_per_node:.1f}", str(stats.cycles)]
    return ";".join(s.replace(";", ",").replace("\n", " ") for s in f)


def results_block(stats: Stats, real_elapsed: float, comm_delay: float) -> str:
    """One ``_results.txt`` block, byte-compatible with the original's layout."""
    L: List[str] = ["", f"Complete Patrol Cycles:\t{stats.cycles}", "",
                    "Vertex\tAvg Idl\tStdDev Idl\t#Visits"]
    for v, p in enumerate(stats.per_vertex):
        L.append(f"{v}\t{p.avg:.1f}\t{p.sd:.1f}\t{p.visits}")
    L += ["", "Node idleness",
          f"   worst_avg_idleness (graph) = {stats.worst_avg:.1f}",
          f"   avg_idleness (graph) = {stats.graph_avg:.1f}",
          f"   median_idleness (graph) = {stats.graph_median:.1f}",
          f"   stddev_idleness (graph) = {stats.graph_sd:.1f}",
          "", "Global idleness",
          f"   min = {fmt1(stats.global_min)}",
          f"   avg = {fmt1(stats.global_avg)}",
          f"   stddev = {fmt1(stats.global_sd)}",
          f"   max = {fmt1(stats.global_max)}",
          "",
          f"Interferences\t{stats.interferences}",
          f"Interference rate\t{stats.interference_rate:.2f}",
          f"Visits\t{stats.total_visits}",
          f"Avg visits per node\t{stats.avg_visits_per_node:.1f}",
          f"Time Elapsed\t{stats.elapsed:.1f}",
          f"Real Time Elapsed\t{real_elapsed:.1f}",
          f"Comm delay: {comm_delay:.2f}",
          "-" * 160, "", ""]
    return "\n".join(L) + "\n"


class ResultWriter:
    """Writes one experiment's files under ``prefix`` (parent folders are created).

    ``idleness.csv`` and ``timeresults.csv`` are created with their headers at once,
    ``results.txt`` empty (a block is appended per complete patrol cycle); ``info.csv`` by
    :meth:`write_info`, written to a temporary file and renamed, so it is either complete or
    absent.

    Rows and ``results.txt`` blocks are flushed at once when ``flush_every`` is 0 (the ROS
    monitor: a node killed with SIGKILL loses nothing), otherwise at most ``flush_every``
    wall seconds after they were written (graph mode: a flush per row was 5 % of a graph run's
    CPU time; a SIGKILL loses at most that much wall time of rows, any other ending closes the
    files).
    """

    def __init__(self, prefix: str, info: RunInfo, flush_every: float = 0.0):
        self.prefix = prefix
        self.info = info
        self.flush_every = flush_every
        self._next_flush = time.monotonic() + flush_every
        folder = os.path.dirname(prefix)
        if folder:
            os.makedirs(folder, exist_ok=True)
        self._idl = open(prefix + "_idleness.csv", "a", encoding="utf-8")
        if self._idl.tell() == 0:
            self._idl.write(IDLENESS_HEADER + "\n")
        self._idl.flush()
        self._time = open(prefix + "_timeresults.csv", "w", encoding="utf-8")
        self._time.write(TIMERESULTS_HEADER + "\n")
        self._time.flush()
        # results.txt exists from the start (empty until the first complete patrol cycle)
        self._res = open(prefix + "_results.txt", "a", encoding="utf-8")
        # beyond the original's four files: every visit report after GO, the input of
        # patrolling_sim.monitor.metrics (docs/metrics.md)
        self._visits = open(prefix + "_visits.csv", "a", encoding="utf-8")
        if self._visits.tell() == 0:
            self._visits.write(VISITS_HEADER + "\n")
        self._visits.flush()
        self.info_written = False

    def path(self, suffix: str) -> str:
        return f"{self.prefix}_{suffix}"

    def idleness_row(self, abs_time: float, robot: int, vertex: int, idleness: float,
                     interferences: int) -> None:
        self._idl.write(f"{abs_time:.1f};{robot};{vertex};{idleness:.1f};{interferences}\n")
        self._flush(self._idl)

    def visit_row(self, t_since_go: float, robot: int, vertex: int) -> None:
        """One visit report (``<prefix>_visits.csv``: time since GO; robot; vertex)."""
        self._visits.write(f"{t_since_go:.3f};{robot};{vertex}\n")
        self._flush(self._visits)

    def _flush(self, f) -> None:
        if not self.flush_every:
            f.flush()
        elif time.monotonic() >= self._next_flush:
            self._idl.flush()
            self._visits.flush()
            self._res.flush()
            self._next_flush = time.monotonic() + self.flush_every

    def time_row(self, stats: Stats) -> None:
        self._time.write(f"{stats.elapsed:.1f};{fmt1(stats.global_min)};"
                         f"{fmt1(stats.global_avg)};{fmt1(stats.global_sd)};"
                         f"{fmt1(stats.global_max)};{stats.interferences}\n")
        self._time.flush()

    def cycle_block(self, stats: Stats, real_elapsed: float) -> None:
        self._res.write(results_block(stats, real_elapsed, self.info.comm_delay))
        self._flush(self._res)

    def write_info(self, stats: Stats, real_elapsed: float, termination: str) -> str:
        """Write ``info.csv`` atomically; returns its path."""
        path = write_atomic(self.path("info.csv"),
                            info_line(self.info, stats, real_elapsed, termination) + "\n")
        self.info_written = True
        return path

    def close(self) -> None:
        """Close every file, even if flushing one fails (a full disk); then raise the first
        error, its ``filename`` set to that file."""
        first = None
        for f in (self._idl, self._time, self._visits, self._res):
            if not f.closed:
                try:
                    f.close()
                except OSError as e:
                    e.filename = e.filename or f.name
                    first = first or e
        if first is not None:
            raise first


def parse_info_line(text: str, path: str = "info.csv") -> dict:
    """Parse an info.csv line into a dict keyed by :data:`INFO_FIELDS` (numbers converted).
    Raises ValueError naming ``path`` if the line is malformed."""
    fields = text.strip().split(";")
    if len(fields) != len(INFO_FIELDS):
        raise ValueError(f"{path}: expected {len(INFO_FIELDS)} ';'-separated fields, "
                         f"got {len(fields)}")
    d = dict(zip(INFO_FIELDS, fields))
    try:
        for k in ("team_size", "interferences", "total_visits", "complete_cycles"):
            d[k] = int(d[k])
        for k in ("goal_wait", "comm_delay", "sim_duration", "real_duration", "idl_min",
                  "idl_avg", "idl_stddev", "idl_max", "interference_rate",
                  "avg_visits_per_node"):
            # an empty idleness field: no sample (None)
            d[k] = None if d[k] == "" and k.startswith("idl_") else float(d[k])
    except ValueError as e:
        raise ValueError(f"{path}: field '{k}' is not a number ({d[k]!r})") from e
    return d
