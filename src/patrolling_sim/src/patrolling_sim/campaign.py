"""Campaigns: a grid of experiments run on Dask, resumable, ending in one tidy table.

A *campaign file* (YAML) names the mode and the runs::

    name: demo                 # optional, default: the file's name
    mode: graph                # graph (graph-level simulator) | ros (the full stack)
    fixed:                     # settings shared by every run
      duration: 600
    grid:                      # every combination of these values is one run
      map: [grid, cumberland]
      robots: [2, 4]
      alg: [CR, CGG]           # "all": every registered algorithm (map: all: every map)
    seeds: 3                   # shorthand for grid.seed = [0, 1, 2]

The keys of ``fixed`` and ``grid`` are the fields of the mode's configuration
(:class:`~patrolling_sim.graph_sim.GraphSimConfig` for graph mode,
:class:`~patrolling_sim.runner.config.ExperimentConfig` for ROS mode), so a key added to
either is available to campaigns at once. Every run is validated before anything starts.

Every run has a stable *key*: a hash of its mode, its full configuration (defaults
included) and the code version (git commit). The campaign folder keeps one state record per
run (``state/<key>.yaml``); re-running the same command skips runs that ended normally
(TIMEOUT, CYCLES, FAIL), redoes incomplete ones (interrupted, aborted, never finished) and,
with ``retry_failed``, crashed ones. Results travel back through Dask (no shared file
system) and only the client writes files: the usual result files in the usual tree under
``results/``, plus ``<prefix>_visits.csv`` and ``<prefix>_metrics.yaml``
(:mod:`patrolling_sim.metrics`), and ``runs.csv``, one row per run. See
``docs/campaigns.md``.
"""
import asyncio
import dataclasses
import datetime
import hashlib
import itertools
import json
import os
import platform
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional

import yaml

from . import paths
from .errors import PatrolInputError

MODES = ("graph", "ros")
#: statuses of a run that ended normally: skipped when the campaign is run again
DONE_STATUSES = ("TIMEOUT", "CYCLES", "FAIL")
#: statuses redone only with ``retry_failed``
FAILED_STATUSES = ("CRASHED", "ERROR")
TOP_KEYS = ("name", "mode", "fixed", "grid", "seeds")
#: configuration keys a campaign may not set (the campaign decides them)
RESERVED = {"graph": ("results_dir",),
            "ros": ("results_dir", "rviz", "gui_sim", "record", "record_period")}
STATE_DIR = "state"
#: LibYAML's emitter when PyYAML has it (Debian's does): records are written per run
_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
RESULTS_DIR = "results"


@dataclass
class RunSpec:
    key: str
    mode: str
    config: Dict[str, object]

    def label(self):
        c = self.config
        return f"{c.get('map')}_{c.get('robots')} {c.get('alg')} seed {c.get('seed')}"


@dataclass
class Campaign:
    name: str
    mode: str
    path: str
    runs: List[RunSpec]
    raw: dict
    code: Dict[str, object]


# ----------------------------------------------------------------------------- configuration
def _config_class(mode):
    if mode == "graph":
        from .graph_sim import GraphSimConfig
        return GraphSimConfig
    from .runner.config import ExperimentConfig
    return ExperimentConfig


def config_fields(mode) -> Dict[str, dataclasses.Field]:
    """Configuration keys of ``mode`` a campaign may set -> dataclass field."""
    return {f.name: f for f in dataclasses.fields(_config_class(mode))
            if f.name not in RESERVED[mode]}


def _default(f):
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def _check_type(where, key, value, f):
    """One-line error unless ``value`` fits field ``f`` (by its default's type)."""
    proto = _default(f)
    ok = True
    if key in ("map", "alg", "initpos") or isinstance(proto, str):
        ok = isinstance(value, str) or (key == "initpos" and isinstance(value, int))
        want = "a string"
    elif isinstance(proto, bool):
        ok, want = isinstance(value, bool), "true or false"
    elif isinstance(proto, int) or key in ("robots", "seed", "cycles"):
        ok, want = isinstance(value, int) and not isinstance(value, bool), "an integer"
    elif isinstance(proto, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        want = "a number"
    elif isinstance(proto, dict):
        ok, want = isinstance(value, dict), "a mapping"
    if not ok:
        raise PatrolInputError(f"{where}.{key}: expected {want}, got {value!r}")


def code_version(root: Optional[str] = None) -> Dict[str, object]:
    """``{"commit": sha or "unknown", "dirty": bool or None}`` of the workspace."""
    root = root or paths.data_root()
    try:
        commit = subprocess.run(["git", "-C", root, "rev-parse", "HEAD"], capture_output=True,
                                text=True, timeout=10, check=True).stdout.strip()
        status = subprocess.run(["git", "-C", root, "status", "--porcelain", "--", "src",
                                 "scripts", "maps", "params", "MSP"], capture_output=True,
                                text=True, timeout=10, check=True).stdout
        return {"commit": commit, "dirty": bool(status.strip())}
    except (OSError, subprocess.SubprocessError):
        return {"commit": "unknown", "dirty": None}


def run_key(mode: str, config: dict, commit: str) -> str:
    blob = json.dumps({"mode": mode, "config": config, "code": commit}, sort_keys=True,
                      default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:16]


def load_campaign(path: str, code: Optional[Dict[str, object]] = None) -> Campaign:
    """Read and validate a campaign file; every run is validated.

    Raises:
        PatrolInputError: one line naming the file and the key that is wrong.
    """
    try:
        with open(path) as f:
            raw = yaml.safe_load(f)
    except OSError as e:
        raise PatrolInputError(f"{path}: cannot read the campaign file ({e.strerror})")
    except yaml.YAMLError as e:
        line = getattr(getattr(e, "problem_mark", None), "line", None)
        raise PatrolInputError(f"{path}: not valid YAML" +
                               (f" (line {line + 1})" if line is not None else ""))
    if not isinstance(raw, dict):
        raise PatrolInputError(f"{path}: expected a mapping with the keys {', '.join(TOP_KEYS)}")
    for k in raw:
        if k not in TOP_KEYS:
            raise PatrolInputError(f"{path}: unknown key '{k}' (known: {', '.join(TOP_KEYS)})")
    mode = raw.get("mode", "graph")
    if mode not in MODES:
        raise PatrolInputError(f"{path}: mode: expected one of {', '.join(MODES)}, got {mode!r}")
    fields = config_fields(mode)
    fixed = raw.get("fixed") or {}
    grid = raw.get("grid") or {}
    for where, d in (("fixed", fixed), ("grid", grid)):
        if not isinstance(d, dict):
            raise PatrolInputError(f"{path}: {where}: expected a mapping of configuration keys")
        for k in d:
            if k not in fields:
                raise PatrolInputError(f"{path}: {where}.{k}: unknown configuration key for mode "
                                       f"{mode} (known: {', '.join(sorted(fields))})")
    if "seeds" in raw:
        n = raw["seeds"]
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise PatrolInputError(f"{path}: seeds: expected an integer >= 1, got {n!r}")
        if "seed" in grid:
            raise PatrolInputError(f"{path}: seeds: give either seeds or grid.seed, not both")
        grid = dict(grid, seed=list(range(n)))
    grid = dict(grid)
    for k in ("map", "alg"):                   # "all": every shipped map / registered algorithm
        if grid.get(k) == "all":
            if k == "map":
                grid[k] = paths.available_maps()
            else:
                from .algorithms import names
                grid[k] = names()
    for k, values in grid.items():
        if not isinstance(values, list):
            raise PatrolInputError(f"{path}: grid.{k}: expected a list of values")
        if not values:
            raise PatrolInputError(f"{path}: grid.{k}: empty list (no run would be made)")
        for v in values:
            _check_type(f"{path}: grid", k, v, fields[k])
    for k, v in fixed.items():
        _check_type(f"{path}: fixed", k, v, fields[k])
    for k in set(fixed) & set(grid):
        raise PatrolInputError(f"{path}: {k}: set both in fixed and in grid")
    for where, values in (("fixed", [fixed["map"]] if "map" in fixed else []),
                          ("grid", grid.get("map", []))):
        for m in values:
            try:
                yaml_path, graph_path = paths.map_files(m)
            except PatrolInputError as e:
                raise PatrolInputError(f"{path}: {where}.map: {e}")
            if not os.path.isfile(graph_path):
                raise PatrolInputError(f"{path}: {where}.map: no graph file {graph_path}")
    code = code or code_version()
    cls = _config_class(mode)
    keys = list(grid)
    runs = []
    for combo in itertools.product(*(grid[k] for k in keys)):
        cfg = {n: _default(f) for n, f in fields.items()}
        cfg.update(fixed)
        cfg.update(zip(keys, combo))
        where = ", ".join(f"{k}={v}" for k, v in zip(keys, combo)) or "the fixed settings"
        try:
            obj = cls(**cfg)
            obj.validate()
        except PatrolInputError as e:
            raise PatrolInputError(f"{path}: run with {where}: {e}")
        except (TypeError, ValueError) as e:
            raise PatrolInputError(f"{path}: run with {where}: {e}")
        runs.append(RunSpec(run_key(mode, cfg, str(code["commit"])), mode, cfg))
    if not runs:
        raise PatrolInputError(f"{path}: no run (give grid values or fixed settings)")
    if len({r.key for r in runs}) != len(runs):
        raise PatrolInputError(f"{path}: the grid repeats a run (same configuration twice)")
    name = raw.get("name") or os.path.splitext(os.path.basename(path))[0]
    return Campaign(str(name), mode, os.path.abspath(path), runs, raw, code)


# ----------------------------------------------------------------------------- workers
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


def run_graph_task(config: dict) -> dict:
    """Worker side of a graph-mode run: simulate in a private temporary folder and return every
    file written (relative path -> text), the visit log included, plus provenance. Runs in a
    Dask worker process, which keeps its imports between runs."""
    from .graph_sim import GraphSimConfig, GraphSimulator
    t0 = datetime.datetime.now(datetime.timezone.utc)
    wall = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="campaign_") as tmp:
        sim = GraphSimulator(GraphSimConfig(**dict(config, results_dir=tmp)))
        sim.run(write=True)                    # the writer keeps the visit log too
        prefix = os.path.relpath(sim.prefix, tmp)
        files = _read_tree(tmp)
    t1 = datetime.datetime.now(datetime.timezone.utc)
    return {"prefix": prefix, "files": files, "status": sim.termination, "rc": 0,
            "wall": time.monotonic() - wall, "provenance": _provenance(t0, t1)}


def run_ros_task(config: dict, root: str) -> dict:
    """Worker side of a ROS-mode run: the runner (its own ROS master) in a private temporary
    results folder; returns every text file it wrote and its exit code."""
    t0 = datetime.datetime.now(datetime.timezone.utc)
    wall = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="campaign_ros_") as tmp:
        cfg_path = os.path.join(tmp, "run.yaml")
        res = os.path.join(tmp, "results")
        with open(cfg_path, "w") as f:
            yaml.safe_dump(dict(config, results_dir=res), f)
        env = dict(os.environ, PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))
        proc = subprocess.run(["/usr/bin/python3", os.path.join(root, "scripts",
                                                                "start_experiments.py"),
                               "--headless", "--config", cfg_path],
                              env=env, capture_output=True, text=True,
                              stdin=subprocess.DEVNULL)
        files = _read_tree(res) if os.path.isdir(res) else {}
    infos = [p for p in files if p.endswith("_info.csv")]
    prefix = infos[0][:-len("_info.csv")] if infos else None
    status = None
    if prefix:
        status = _status_from_files(files, prefix)
    if status is None:
        status = "CRASHED"
    t1 = datetime.datetime.now(datetime.timezone.utc)
    return {"prefix": prefix, "files": files, "status": status, "rc": proc.returncode,
            "wall": time.monotonic() - wall, "provenance": _provenance(t0, t1),
            "log_tail": (proc.stdout + proc.stderr)[-2000:]}


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
    from .results import INFO_FIELDS
    if len(info) == len(INFO_FIELDS):
        return info[INFO_FIELDS.index("termination")]
    return None


# ----------------------------------------------------------------------------- client side
def _write_atomic(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + ".part"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def load_state(out: str) -> Dict[str, dict]:
    d = os.path.join(out, STATE_DIR)
    state = {}
    if os.path.isdir(d):
        for fn in sorted(os.listdir(d)):
            if fn.endswith(".yaml"):
                with open(os.path.join(d, fn)) as f:
                    rec = yaml.load(f, Loader=_Loader) or {}
                if "key" in rec:
                    state[rec["key"]] = rec
    return state


def needs_run(record: Optional[dict], retry_failed: bool) -> bool:
    if record is None:
        return True
    st = record.get("status")
    if st in DONE_STATUSES:
        return False
    if st in FAILED_STATUSES:
        return retry_failed
    return True                                # interrupted, aborted, unknown: redo


def _summary_from_info(text):
    """The original's metrics of an info.csv line (empty idleness fields: None), {} if the
    line is malformed."""
    from .results import parse_info_line
    try:
        row = parse_info_line(text)
    except ValueError:
        return {}
    return {k: (None if row[k] is None else float(row[k]))
            for k in ("idl_min", "idl_avg", "idl_stddev", "idl_max", "interferences",
                      "total_visits", "complete_cycles", "sim_duration", "interference_rate")}


def store_result(out: str, spec: RunSpec, result: dict, campaign: Campaign) -> dict:
    """Write a finished run's files into the campaign tree and its state record (last, so a
    record always points at complete files). Returns the record."""
    from .metrics import compute_metrics, metrics_to_yaml_dict, read_visits
    files = result.get("files") or {}
    prefix = result.get("prefix")
    dest_prefix = None
    metrics = {}
    if prefix:
        base = os.path.join(out, RESULTS_DIR)
        rel = prefix
        # a stamp may repeat across runs (same second): keep every run's files apart
        k = 0
        while any(os.path.exists(os.path.join(base, (rel if k == 0 else f"{prefix}_{k}") + s))
                  for s in ("_info.csv", "_idleness.csv")):
            k += 1
        if k:
            rel = f"{prefix}_{k}"
        for p, text in files.items():
            target = rel + p[len(prefix):] if p.startswith(prefix) else p
            _write_atomic(os.path.join(base, target), text)
        dest_prefix = os.path.join(RESULTS_DIR, rel)
        info = files.get(prefix + "_info.csv", "")
        metrics.update(_summary_from_info(info))
        vpath = os.path.join(out, dest_prefix + "_visits.csv")
        if os.path.isfile(vpath) and metrics.get("sim_duration"):
            n = paths.vertex_count(spec.config["map"])
            m = compute_metrics(read_visits(vpath), n, metrics["sim_duration"])
            md = metrics_to_yaml_dict(m)
            _write_atomic(os.path.join(out, dest_prefix + "_metrics.yaml"),
                          yaml.dump(md, Dumper=_Dumper, sort_keys=False))
            for k in ("time_avg_idleness", "worst_idleness", "time_avg_max_idleness",
                      "visit_frequency_mean", "visit_frequency_sd", "never_visited"):
                metrics[k] = md[k]
            for k, v in md["idleness_percentiles"].items():
                metrics[f"idl_{k}"] = v
    record = {"key": spec.key, "mode": spec.mode, "config": spec.config,
              "status": result.get("status") or "CRASHED", "rc": result.get("rc"),
              "prefix": dest_prefix, "wall": round(float(result.get("wall") or 0.0), 3),
              "code": campaign.code, "provenance": result.get("provenance"),
              "metrics": metrics}
    if result.get("error"):
        record["error"] = result["error"]
    if result.get("log_tail") and record["status"] not in DONE_STATUSES:
        record["log_tail"] = result["log_tail"]
    _write_atomic(os.path.join(out, STATE_DIR, spec.key + ".yaml"),
                  yaml.dump(record, Dumper=_Dumper, sort_keys=False))
    return record


def write_table(out: str, campaign: Campaign, state: Dict[str, dict]) -> str:
    """``runs.csv``: one row per run of the campaign (config columns, status, metrics)."""
    import pandas as pd
    rows = []
    for spec in campaign.runs:
        rec = state.get(spec.key)
        row = {"key": spec.key, "mode": spec.mode}
        row.update({k: (json.dumps(v) if isinstance(v, (dict, list)) else v)
                    for k, v in spec.config.items()})
        row["status"] = rec["status"] if rec else "NOT_RUN"
        if rec:
            row["prefix"] = rec.get("prefix")
            row["wall_s"] = rec.get("wall")
            row.update(rec.get("metrics") or {})
        rows.append(row)
    path = os.path.join(out, "runs.csv")
    df = pd.DataFrame(rows)
    tmp = path + ".part"
    df.to_csv(tmp, index=False)
    os.replace(tmp, path)
    return path


def summary_table(out: str) -> str:
    """Text table of runs.csv grouped by map, team size and algorithm."""
    import pandas as pd
    df = pd.read_csv(os.path.join(out, "runs.csv"))
    ok = df[df["status"].isin(DONE_STATUSES[:2])]
    lines = []
    if len(ok):
        g = ok.groupby(["map", "robots", "alg"])
        t = g.agg(runs=("key", "count"), avg_idleness=("idl_avg", "mean"),
                  max_idleness=("idl_max", "mean"), visits=("total_visits", "mean"))
        if "time_avg_idleness" in ok:
            t["time_avg_idleness"] = g["time_avg_idleness"].mean()
        lines.append(t.round(2).to_string())
    counts = df["status"].value_counts().to_dict()
    lines.append("status: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    return "\n".join(lines)


class _Progress:
    def __init__(self, total, skipped, stream=sys.stdout):
        self.total, self.done, self.failed = total, 0, 0
        self.skipped = skipped
        self.t0 = time.monotonic()
        self.stream = stream
        self.tty = hasattr(stream, "isatty") and stream.isatty()

    def update(self, record, running):
        self.done += 1
        if record["status"] not in DONE_STATUSES:
            self.failed += 1
        el = time.monotonic() - self.t0
        left = self.total - self.done
        eta = el / self.done * left if self.done else 0.0
        width = 24
        fill = int(width * self.done / max(1, self.total))
        bar = "#" * fill + "." * (width - fill)
        c = record["config"]
        line = (f"[{bar}] {self.done}/{self.total} done, {running} running, {self.failed} "
                f"failed, ETA {int(eta // 60)}m{int(eta % 60):02d}s | last: {c.get('map')}_"
                f"{c.get('robots')} {c.get('alg')} seed {c.get('seed')} {record['status']}")
        if self.tty:
            self.stream.write("\r" + line[:160].ljust(160))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()


def _env_for_workers():
    """Make the workspace's packages importable in worker processes started from here."""
    src = os.path.join(paths.data_root(), "src", "patrolling_sim", "src")
    pp = os.environ.get("PYTHONPATH", "")
    if src not in pp.split(os.pathsep):
        os.environ["PYTHONPATH"] = src + (os.pathsep + pp if pp else "")


def run_campaign(campaign: Campaign, out: str, scheduler: Optional[str] = None,
                 workers: Optional[int] = None, retry_failed: bool = False,
                 limit: Optional[int] = None, stream=sys.stdout,
                 on_record: Optional[Callable[[dict], None]] = None) -> dict:
    """Run what is left of ``campaign`` into the folder ``out``.

    Args:
        scheduler: address of an existing Dask scheduler (``tcp://host:8786``); None starts a
            LocalCluster sized to this machine and stops it at the end.
        workers: LocalCluster size (graph mode: worker processes, one run at a time each;
            ROS mode: concurrent experiments). Default: the core count (graph), half of it,
            at least 1 (ROS).
        retry_failed: also redo crashed runs.
        limit: submit at most this many runs (tests, dry runs).
        on_record: called with each stored record (tests).

    Returns:
        ``{"ran": n, "skipped": n, "interrupted": bool, "table": path}``.
    Ctrl-C (or SIGTERM) stops cleanly: runs in progress are cancelled, every finished run's
    files and record are complete, and the next call resumes.
    """
    from distributed import Client, LocalCluster, wait
    os.makedirs(out, exist_ok=True)
    _write_atomic(os.path.join(out, "campaign.yaml"), yaml.safe_dump(campaign.raw,
                                                                    sort_keys=False))
    state = load_state(out)
    todo = [r for r in campaign.runs if needs_run(state.get(r.key), retry_failed)]
    skipped = len(campaign.runs) - len(todo)
    if limit is not None:
        todo = todo[:limit]
    started = datetime.datetime.now(datetime.timezone.utc)
    prov = {"name": campaign.name, "mode": campaign.mode, "file": campaign.path,
            "runs": len(campaign.runs), "code": campaign.code, "client_host": socket.gethostname(),
            "python": platform.python_version(), "packages": _package_versions(),
            "start": started.isoformat(timespec="seconds")}
    interrupted = {"sig": None}
    ran = 0
    cluster = client = None

    # while results are being collected a signal only sets the flag (checked between two
    # stored runs, so a run's files and record are never cut half-way); before that, it
    # interrupts at once. Python runs the handler in the main thread whichever thread the
    # signal hit, so the flag is the only safe way with Dask's threads around.
    collecting = {"on": False}

    def on_signal(signum, _frame):
        interrupted["sig"] = signum
        if not collecting["on"]:
            raise KeyboardInterrupt

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        if not todo:
            stream.write(f"campaign {campaign.name}: {len(campaign.runs)} runs, {skipped} already "
                         "done, 0 to run\n")
        if todo:
            cores = os.cpu_count() or 1
            if scheduler:
                client = Client(scheduler, timeout="30s")
            else:
                _env_for_workers()
                n = workers or (cores if campaign.mode == "graph" else max(1, cores // 2))
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=30,
                                       resources={"experiment": 1})
                client = Client(cluster)
            link = getattr(client, "dashboard_link", None)
            stream.write(f"campaign {campaign.name}: {len(campaign.runs)} runs, {skipped} already "
                         f"done, {len(todo)} to run on {len(client.scheduler_info()['workers'])} "
                         f"worker(s)" + (f"; dashboard {link}" if link and cluster is None
                                        else "") + "\n")
            # one map() call: Dask inspects the caller's source once per call, not per run
            if campaign.mode == "graph":
                flist = client.map(run_graph_task, [r.config for r in todo], pure=False)
            else:
                flist = client.map(run_ros_task, [r.config for r in todo],
                                   [paths.data_root()] * len(todo), pure=False,
                                   resources={"experiment": 1} if cluster else None)
            futs = dict(zip(flist, todo))
            progress = _Progress(len(todo), skipped, stream)
            n_workers = max(1, len(client.scheduler_info()["workers"]))
            collecting["on"] = True
            pending = list(futs)
            while pending and interrupted["sig"] is None:
                try:
                    ready = wait(pending, timeout=0.5, return_when="FIRST_COMPLETED").done
                except (TimeoutError, asyncio.TimeoutError):
                    continue
                ready = [f for f in pending if f in ready]
                for fut in ready:
                    pending.remove(fut)
                    spec = futs.pop(fut)
                    try:
                        result = fut.result()
                    except Exception as e:         # the task raised: record it, go on
                        result = {"status": "ERROR", "error": f"{type(e).__name__}: {e}"}
                    rec = store_result(out, spec, result, campaign)
                    state[spec.key] = rec
                    ran += 1
                    progress.update(rec, min(len(pending), n_workers))
                    if on_record:
                        on_record(rec)
                    if interrupted["sig"] is not None:
                        break
            collecting["on"] = False
            if interrupted["sig"] is not None:
                raise KeyboardInterrupt
            if progress.tty:
                stream.write("\n")
    except KeyboardInterrupt:
        stream.write(f"\ncampaign {campaign.name}: interrupted after {ran} run(s); run the same "
                     "command again to resume\n")
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        if client is not None:
            try:
                client.close()
            except Exception:
                pass
        if cluster is not None:
            try:
                cluster.close()
            except Exception:
                pass
        table = write_table(out, campaign, state)
        prov["end"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        prov["interrupted"] = interrupted["sig"] is not None
        _write_atomic(os.path.join(out, "provenance.yaml"), yaml.safe_dump(prov, sort_keys=False))
    return {"ran": ran, "skipped": skipped, "interrupted": interrupted["sig"] is not None,
            "signal": interrupted["sig"], "table": table}


def _package_versions():
    out = {}
    for mod in ("numpy", "scipy", "networkx", "pandas", "dask", "distributed", "yaml"):
        try:
            out[mod] = str(__import__(mod).__version__)
        except Exception:
            out[mod] = None
    return out


def main(argv=None):
    from .cli import CliParser, run_main

    def _main(args):
        ap = CliParser(prog="campaign.py", description=(
            "Run a campaign (a grid of experiments, graph or ROS mode) on Dask: a LocalCluster "
            "on this machine by default, or an existing cluster with --scheduler. Re-running "
            "the same command resumes (finished runs are skipped)."))
        ap.add_argument("campaign", help="campaign file (YAML)")
        ap.add_argument("--out", help="campaign folder (default: results/campaigns/<name>)")
        ap.add_argument("--scheduler", help="address of a running Dask scheduler")
        ap.add_argument("--workers", type=int, help="LocalCluster size (default: the cores for "
                        "graph mode, half of them for ROS mode)")
        ap.add_argument("--retry-failed", action="store_true", help="redo crashed runs too")
        ap.add_argument("--limit", type=int, help="run at most this many runs now")
        ap.add_argument("--dry-run", action="store_true",
                        help="validate and list the runs, run nothing")
        ap.add_argument("--no-report", action="store_true", help="skip the HTML report")
        a = ap.parse_args(args)
        if a.workers is not None and a.workers < 1:
            ap.error(f"argument --workers: must be >= 1, got {a.workers}")
        if a.limit is not None and a.limit < 1:
            ap.error(f"argument --limit: must be >= 1, got {a.limit}")
        camp = load_campaign(a.campaign)
        out = a.out or os.path.join(paths.data_root(), "results", "campaigns", camp.name)
        if a.dry_run:
            state = load_state(out) if os.path.isdir(out) else {}
            for r in camp.runs:
                todo = needs_run(state.get(r.key), a.retry_failed)
                print(f"{r.key}  {'run ' if todo else 'done'}  {r.label()}")
            return 0
        res = run_campaign(camp, out, scheduler=a.scheduler, workers=a.workers,
                           retry_failed=a.retry_failed, limit=a.limit)
        print(summary_table(out))
        print(f"table: {res['table']}")
        if not a.no_report and not res["interrupted"] and os.path.isdir(
                os.path.join(out, RESULTS_DIR)):
            from .report.build import build_report
            try:
                build_report([os.path.join(out, RESULTS_DIR)], os.path.join(out, "report"))
                print(f"report: {os.path.join(out, 'report', 'report.html')}")
            except Exception as e:             # the table is the product; say why no report
                print(f"campaign.py: warning: no report ({type(e).__name__}: {e})")
        if res["interrupted"]:
            return 130 if res["signal"] == signal.SIGINT else 143
        return 0
    return run_main(_main, "campaign.py", argv)
