"""Worker side of a campaign: one run (or a chunk of graph-mode runs) executed in a Dask worker
process, returning everything in memory (file contents, the metrics row, provenance). Part of
:mod:`patrolling_sim.campaign.engine`."""
import datetime
import gc
import logging
import os
import platform
import resource
import signal
import socket
import subprocess
import tempfile
import threading
import time
from typing import Dict, List

import yaml

from patrolling_sim.campaign.run_warnings import RunWarnings
from patrolling_sim.common.textfile import YamlDumper
from patrolling_sim.common import paths
from patrolling_sim.model import map_bundle
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.simulator import start_vertices_of
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.monitor.metrics import compute_metrics
from patrolling_sim.monitor.metrics import metrics_to_yaml_dict
from patrolling_sim.monitor.metrics import read_visits
from patrolling_sim.monitor.results import INFO_FIELDS
from patrolling_sim.monitor.results import parse_info_line
from patrolling_sim.monitor.run_status import longest_silence
from patrolling_sim.monitor.run_status import silences_of
from patrolling_sim.scenarios.scenario import scenario_columns
from patrolling_sim.scenarios.scenario import scenario_metrics
from patrolling_sim.startpos.explicit import RANDOM
from patrolling_sim.startpos.explicit import VERTICES
from patrolling_sim.startpos.explicit import parse_initpos
from patrolling_sim.startpos.explicit import start_file_path
from patrolling_sim.startpos.initial_poses import OPTIMISED


def _ignore(signum, frame):
    """A handler that does nothing (see :class:`IgnoreGroupSignals`)."""


class IgnoreGroupSignals:
    """Worker plugin (``distributed.WorkerPlugin`` protocol) that the campaign registers on
    the workers of the LocalCluster it starts.

    Those workers share the campaign's process group, so a terminal's Ctrl-C (SIGINT), or a
    SIGTERM sent to the group (``kill -TERM -PGID``, a batch system ending a job), reaches
    them as well as the campaign. Dask's worker process then died in its own traceback
    after the campaign's clean "interrupted" line, and with SIGTERM its Nanny restarted it
    and printed some 80 lines of errors while the campaign was stopping. With this plugin a
    worker lets both signals pass; the campaign stops its cluster itself (the Nanny asks
    each worker to close and kills it if it does not). The signals get a handler that does
    nothing rather than SIG_IGN: an ignored signal is inherited by the programs a worker
    starts, a handled one is reset to its default at their start, so a ROS run started by a
    worker still stops on them (it installs its own handlers, scripts/early_signal.py)."""

    def setup(self, worker=None):
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, _ignore)
            signal.signal(signal.SIGTERM, _ignore)
        log = logging.getLogger("distributed.worker")
        if not any(isinstance(f, SchedulerGoneFirst) for f in log.filters):
            log.addFilter(SchedulerGoneFirst())


class SchedulerGoneFirst(logging.Filter):
    """Drops the two records a LocalCluster worker logs when the campaign closes its cluster
    while that worker is still busy with a run (after an interruption): the scheduler, in the
    campaign's own process, has already let the worker go, so the worker's next heartbeat
    fails ("Failed to communicate with scheduler during heartbeat", with a traceback of
    Dask's comm layer) and the scheduler's answer ends it ("Scheduler was unaware of this
    worker"). Both say only that the campaign is stopping, which it reports itself. Only the
    campaign's own LocalCluster workers get this filter (with :class:`IgnoreGroupSignals`),
    never a user's cluster."""

    DROP = ("Failed to communicate with scheduler during heartbeat",
            "Scheduler was unaware of this worker")

    def filter(self, record):
        return not str(record.msg).startswith(self.DROP)


class WorldCache:
    """Patrol graphs (per map) and start vertices (per map, team size and initpos; and
    algorithm for "optimised", seed for "random", the start file's stamp for a start file),
    built once per worker process: a campaign runs the same few
    worlds hundreds of times, and loading the map image, its clearance and the start
    positions was a tenth of a run's CPU time. Keyed on the files read (path, size, mtime),
    so an edited file is loaded again. A graph is shared read-only by the runs of its map
    (its shortest-path tables, computed on first use, are kept); every run builds its own
    agents and monitor."""

    def __init__(self, size: int = 4096):
        self.size = size
        self._graphs = {}
        self._starts = {}

    @staticmethod
    def _stamp(path):
        st = os.stat(path)
        return (path, st.st_size, st.st_mtime_ns)

    def _put(self, table, key, value):
        if len(table) >= self.size:
            table.pop(next(iter(table)))
        table[key] = value
        return value

    def _start_input(self, cfg, yaml_path):
        """What else the start of ``cfg`` depends on: the seed of a random start, the stamp
        of a start file (None if it is missing: resolving the start then fails), else
        None."""
        form = parse_initpos(cfg.initpos)
        if form is None or form.kind == VERTICES:
            return None
        if form.kind == RANDOM:
            return cfg.seed
        path = start_file_path(form.path, os.path.dirname(os.path.abspath(yaml_path)))
        try:
            return self._stamp(path)
        except OSError:
            return None

    def get(self, cfg):
        """(PatrolGraph, start vertices) of the GraphSimConfig ``cfg``."""
        cfg.validate()                           # as the run's GraphSimulator would, first
        yaml_path, graph_path = paths.map_files(cfg.map)
        gkey = self._stamp(graph_path)
        g = self._graphs.get(gkey)
        if g is None:
            g = self._put(self._graphs, gkey, PatrolGraph.load(graph_path))
        skey = (self._stamp(yaml_path), gkey, self._stamp(paths.initial_poses_file()),
                cfg.robots, cfg.initpos, cfg.alg if cfg.initpos == OPTIMISED else None,
                self._start_input(cfg, yaml_path))
        starts = self._starts.get(skey)
        if starts is None:
            starts = self._put(self._starts, skey, tuple(start_vertices_of(cfg, g)))
        return g, starts


def worker_worlds() -> "WorldCache":
    """The WorldCache of the Dask worker running this task, kept on the worker object (one
    per worker process, as long as the worker lives); outside a worker, a new empty one."""
    try:
        from distributed import get_worker
        worker = get_worker()
    except (ImportError, ValueError):          # not in a Dask task
        return WorldCache()
    worlds = getattr(worker, "patrolling_sim_worlds", None)
    if worlds is None:
        worlds = worker.patrolling_sim_worlds = WorldCache()
        # the worker's first graph run: what the process holds now (Dask, the simulator's
        # modules) lives as long as it does, so the cyclic garbage collector need not walk it
        # again at each of its full collections during the runs (1-1.5 % of a graph run's
        # CPU time, bench/notes/campaign.md); objects made from now on are collected as
        # usual
        gc.freeze()
    return worlds


def _read_tree(root: str) -> Dict[str, str]:
    out = {}
    for d, _, files in os.walk(root):
        for fn in files:
            p = os.path.join(d, fn)
            try:
                with open(p) as f:
                    out[os.path.relpath(p, root)] = f.read()
            except (UnicodeDecodeError, OSError):
                continue                       # binary (snapshots) or vanished: not sent back
    return out


def _provenance(t0, t1):
    return {"host": socket.gethostname(), "python": platform.python_version(),
            "start": t0.isoformat(timespec="seconds"), "end": t1.isoformat(timespec="seconds")}


def _tmp_root():
    """A memory-backed folder for the runs' scratch files when the machine has one (the files
    are read back at once and deleted), else the default temporary folder."""
    shm = "/dev/shm"
    return shm if os.path.isdir(shm) and os.access(shm, os.W_OK) else None


def _summary_from_info(text):
    """The original's metrics of an info.csv line (empty idleness fields: None), {} if the
    line is malformed."""
    try:
        row = parse_info_line(text)
    except ValueError:
        return {}
    return {k: (None if row[k] is None else float(row[k]))
            for k in ("idl_min", "idl_avg", "idl_stddev", "idl_max", "interferences",
                      "total_visits", "complete_cycles", "sim_duration", "interference_rate")}


def _longest_silence(run_yaml):
    """(seconds, robot) of a ``_run.yaml`` text's longest silence, (None, None) without one."""
    if not run_yaml:
        return None, None
    try:
        rec = yaml.load(run_yaml, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError:
        return None, None
    return longest_silence(silences_of(rec if isinstance(rec, dict) else None))


def run_metrics(files: Dict[str, str], prefix: str, map_name: str, visits_path: str) -> dict:
    """The run's row of metrics (the original's from info.csv, the extra ones of
    :mod:`patrolling_sim.monitor.metrics` from the visit log at ``visits_path``); adds
    ``<prefix>_metrics.yaml`` to ``files``. Computed where the run ran, so the client only
    writes what it receives."""
    row = _summary_from_info(files.get(prefix + "_info.csv", ""))
    # the longest time a robot sent no visit report (_run.yaml, docs/monitor.md) and which
    row["longest_silence"], row["longest_silence_robot"] = _longest_silence(
        files.get(prefix + "_run.yaml"))
    if os.path.isfile(visits_path) and row.get("sim_duration"):
        m = compute_metrics(read_visits(visits_path), map_bundle.vertex_count(map_name),
                            row["sim_duration"])
        md = metrics_to_yaml_dict(m)
        files[prefix + "_metrics.yaml"] = yaml.dump(md, Dumper=YamlDumper, sort_keys=False)
        for k in ("time_avg_idleness", "worst_idleness", "time_avg_max_idleness",
                  "visit_frequency_mean", "visit_frequency_sd", "never_visited"):
            row[k] = md[k]
        for k, v in md["idleness_percentiles"].items():
            row[f"idl_{k}"] = v
        full = visits_path[:-len("_visits.csv")]
        if os.path.isfile(full + "_scenario.yaml"):
            # failures / communication model (docs/scenarios.md): per-failure impact in the
            # metrics file, the first failure's figures and the message counters as scn_*
            # columns (prefixed: the config columns already hold comm and attrition)
            n, dur = map_bundle.vertex_count(map_name), row["sim_duration"]
            md["scenario"] = scenario_metrics(full, n, dur)
            files[prefix + "_metrics.yaml"] = yaml.dump(md, Dumper=YamlDumper, sort_keys=False)
            for k, v in scenario_columns(full, n, dur).items():
                row["scn_" + k] = v
    return row


def run_graph_task(config: dict, worlds: "WorldCache" = None) -> dict:
    """Worker side of a graph-mode run: simulate in a private scratch folder and return every
    file written (relative path -> text), the visit log included, the run's metrics row, its
    CPU time and provenance. Runs in a Dask worker process, which keeps its imports between
    runs; ``worlds`` (default: the worker's, :func:`worker_worlds`) supplies graphs and
    start vertices."""
    t0 = datetime.datetime.now(datetime.timezone.utc)
    wall = time.monotonic()
    cpu = time.thread_time()
    with tempfile.TemporaryDirectory(prefix="campaign_", dir=_tmp_root()) as tmp, \
            RunWarnings() as warnings:
        cfg = GraphSimConfig(**dict(config, results_dir=tmp))
        g, starts = (worlds or worker_worlds()).get(cfg)
        sim = GraphSimulator(cfg, start_vertices=starts, pgraph=g)
        sim.run(write=True)                    # the writer keeps the visit log too
        prefix = os.path.relpath(sim.prefix, tmp)
        files = _read_tree(tmp)
        metrics = run_metrics(files, prefix, config["map"], sim.prefix + "_visits.csv")
    t1 = datetime.datetime.now(datetime.timezone.utc)
    out = {"prefix": prefix, "files": files, "status": sim.termination, "rc": 0,
           "metrics": metrics, "cpu_s": time.thread_time() - cpu,
           "wall": time.monotonic() - wall, "provenance": _provenance(t0, t1),
           "start_vertices": list(sim.start_vertices)}
    if warnings.lines:
        out["warnings"] = warnings.lines
    return out


def run_graph_chunk(configs: List[dict]) -> List[dict]:
    """Several graph-mode runs in one Dask task (the engine's cost per task is paid once per
    chunk); a run that raises gives an ERROR result, the others are kept."""
    out = []
    worlds = worker_worlds()
    for c in configs:
        try:
            out.append(run_graph_task(c, worlds))
        except Exception as e:                 # recorded per run, like a failed task
            out.append({"status": "ERROR", "error": f"{type(e).__name__}: {e}"})
    return out


def chunks(n_runs: int, n_workers: int, max_size: int = 20, per_worker: int = 8) -> List[int]:
    """Sizes of the chunks ``n_runs`` runs are cut into: at most ``max_size`` runs each and at
    least ``per_worker`` chunks per worker when there are enough runs (so the workers stay
    busy to the end and an interruption loses little), as even as possible."""
    if n_runs <= 0:
        return []
    k = max(-(-n_runs // max_size), min(n_runs, per_worker * max(1, n_workers)))
    q, r = divmod(n_runs, k)
    return [q + 1] * r + [q] * (k - r)


def run_ros_task(config: dict, runner: str) -> dict:
    """Worker side of a ROS-mode run: the runner program ``runner`` (the path of
    ``start_experiments.py``, :func:`patrolling_sim.common.paths.program`) with its own ROS
    master, in a private temporary results folder; returns every text file it wrote and its
    exit code."""
    t0 = datetime.datetime.now(datetime.timezone.utc)
    wall = time.monotonic()
    cpu = _children_cpu()
    with tempfile.TemporaryDirectory(prefix="campaign_ros_") as tmp:
        cfg_path = os.path.join(tmp, "run.yaml")
        res = os.path.join(tmp, "results")
        with open(cfg_path, "w") as f:
            yaml.safe_dump(dict(config, results_dir=res), f)
        env = dict(os.environ, PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))
        proc = subprocess.run(["/usr/bin/python3", runner, "--headless", "--config", cfg_path],
                              env=env, capture_output=True, text=True,
                              stdin=subprocess.DEVNULL)
        files = _read_tree(res) if os.path.isdir(res) else {}
        infos = [p for p in files if p.endswith("_info.csv")]
        prefix = infos[0][:-len("_info.csv")] if infos else None
        status, metrics = None, {}
        if prefix:
            status = _status_from_files(files, prefix)
            metrics = run_metrics(files, prefix, config["map"],
                                  os.path.join(res, prefix + "_visits.csv"))
    if status is None:
        status = "CRASHED"
    t1 = datetime.datetime.now(datetime.timezone.utc)
    return {"prefix": prefix, "files": files, "status": status, "rc": proc.returncode,
            "metrics": metrics, "cpu_s": _children_cpu() - cpu, "wall": time.monotonic() - wall,
            "provenance": _provenance(t0, t1),
            "log_tail": (proc.stdout + proc.stderr)[-2000:],
            "start_vertices": start_vertices_from_files(files, prefix)}


def start_vertices_from_files(files, prefix):
    """The start vertex of each robot, read from the run's ``<prefix>_start_poses.txt``
    (``robot x y vertex`` lines) in ``files`` (relative path -> text); None without that
    file or with a line that does not read."""
    text = files.get(f"{prefix}_start_poses.txt") if prefix else None
    if text is None:
        return None
    try:
        return [int(line.split()[3]) for line in text.splitlines()
                if line.strip() and not line.startswith("#")]
    except (IndexError, ValueError):
        return None


def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _status_from_files(files, prefix):
    """Run status: ``<prefix>_run.yaml``'s ``status`` if the runner wrote one, else the
    termination field of info.csv."""
    run_yaml = files.get(prefix + "_run.yaml")
    if run_yaml:
        try:
            st = (yaml.safe_load(run_yaml) or {}).get("status")
            if st:
                return str(st)
        except yaml.YAMLError:
            pass
    info = files.get(prefix + "_info.csv", "").strip().split(";")
    if len(info) == len(INFO_FIELDS):
        return info[INFO_FIELDS.index("termination")]
    return None
