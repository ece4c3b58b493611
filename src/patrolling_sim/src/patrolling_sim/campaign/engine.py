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
(:class:`~patrolling_sim.graphsim.simulator.GraphSimConfig` for graph mode,
:class:`~patrolling_sim.runner.config.ExperimentConfig` for ROS mode), so a key added to
either is available to campaigns at once. Every run is validated before anything starts.

Every run has a stable *key*: a hash of its mode, its full configuration (defaults
included) and the code version (git commit). The campaign folder keeps one state record per
run (``state/<key>.yaml``); re-running the same command skips runs that ended normally
(TIMEOUT, CYCLES, FAIL), redoes incomplete ones (interrupted, aborted, never finished) and,
with ``retry_failed``, crashed ones. Results travel back through Dask (no shared file
system) and only the client writes files: the usual result files in the usual tree under
``results/``, plus ``<prefix>_visits.csv`` and ``<prefix>_metrics.yaml``
(:mod:`patrolling_sim.monitor.metrics`), and ``runs.csv``, one row per run. See
``docs/campaigns.md``.
"""
import asyncio
import datetime
import logging
import os
import platform
import signal
import socket
import sys
import time
from typing import Callable, Optional

import yaml

from patrolling_sim.common import paths
from patrolling_sim.campaign.spec import (DONE_STATUSES, FAILED_STATUSES, MODES, RESULTS_DIR,  # noqa: F401
                            STATE_DIR, Campaign, RunSpec, code_version, config_fields,
                            load_campaign, run_key)
from patrolling_sim.campaign.store import (load_state, needs_run, store_result, summary_table,  # noqa: F401
                             write_table, write_atomic)
from patrolling_sim.campaign.forkserver import MARK as FORKSERVER_MARK
from patrolling_sim.campaign.forkserver import drop_unused_version_checks, restore_version_checks
from patrolling_sim.campaign.tasks import IgnoreGroupSignals, chunks, run_graph_chunk, run_graph_task, run_ros_task  # noqa: F401,E501
import threading
from patrolling_sim.common.cli import CliParser
from patrolling_sim.common.cli import run_main
from patrolling_sim.experiment import validation
from patrolling_sim.report.build import build_report
from patrolling_sim.runner.config import NAV_ALIASES


class _Progress:
    """Progress of a campaign: a bar redrawn in place on a terminal, lines in a log. Shown at
    most every TTY_INTERVAL (terminal) or LOG_INTERVAL (log) seconds, so that thousands of
    10-ms graph runs do not write thousands of lines to a log (the reference campaign: 7020;
    for readability, not speed: a line and its flush cost the client about 1 us); a failed
    run and the last run are always shown, and ROS runs, minutes apart, each get their line."""

    #: least seconds between two redraws of the bar on a terminal
    TTY_INTERVAL = 0.1
    #: least seconds between two lines in a log (not a terminal)
    LOG_INTERVAL = 2.0

    def __init__(self, total, skipped, stream=sys.stdout):
        self.total, self.done, self.failed = total, 0, 0
        self.skipped = skipped
        self.t0 = time.monotonic()
        self.shown = None                      # time of the last line shown
        self.stream = stream
        self.tty = hasattr(stream, "isatty") and stream.isatty()

    def update(self, record, running):
        self.done += 1
        failed = record["status"] not in DONE_STATUSES
        if failed:
            self.failed += 1
        now = time.monotonic()
        interval = self.TTY_INTERVAL if self.tty else self.LOG_INTERVAL
        if not (failed or self.done >= self.total or self.shown is None
                or now - self.shown >= interval):
            return
        self.shown = now
        el = now - self.t0
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


#: Dask settings of the LocalCluster's workers: no statistical profiler (it samples the
#: running task's stack every 10 ms, which costs a simulation run several per cent) and a
#: slower event-loop watchdog; passed as environment variables, set before the workers'
#: forkserver starts, so the workers see them
WORKER_DASK_ENV = {"DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False",
                   "DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL": "1s"}


#: a campaign's report draws one idleness-over-time figure per run only up to this many
#: runs (each is a PNG of ~0.2 s; the reference campaign has 7020 runs)
REPORT_RUN_PLOTS_MAX = 200


#: what the forkserver of the LocalCluster's workers imports once, before it forks them
#: (campaign_forkserver first: it makes the server ignore a SIGTERM sent to the process group)
WORKER_PRELOAD = ["patrolling_sim.campaign.forkserver", "distributed",
                  "patrolling_sim.campaign.tasks", "patrolling_sim.graphsim.simulator"]


def _env_for_workers():
    """Make the workspace's packages importable in worker processes started from here, with
    the settings of WORKER_DASK_ENV, and start their forkserver.

    The workers are forked from a server process that has imported WORKER_PRELOAD once,
    not spawned (Dask's default, where each worker starts an interpreter and imports
    ``distributed`` and the simulator itself): the server starts here (from :func:`main`
    before the campaign file is validated; called again from :func:`run_campaign`, it finds
    the server running), before this process imports ``distributed``, and imports on the
    other core while this process prepares, so the cluster's start no longer waits for the
    workers' imports, and two workers import once (docs/benchmarks/campaign.md). A forked
    worker gets the server's environment, so Dask's ``pre-spawn-environ`` (which it sets
    just before spawning) is set here first."""
    src = os.path.join(paths.data_root(), "src", "patrolling_sim", "src")
    pp = os.environ.get("PYTHONPATH", "")
    if src not in pp.split(os.pathsep):
        os.environ["PYTHONPATH"] = src + (os.pathsep + pp if pp else "")
    for k, v in WORKER_DASK_ENV.items():
        os.environ.setdefault(k, v)
    import dask
    dask.config.refresh()
    for k, v in (dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {}).items():
        os.environ.setdefault(k, str(v))
    import multiprocessing
    from multiprocessing import forkserver
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(WORKER_PRELOAD)
    os.environ[FORKSERVER_MARK] = "1"          # seen by the server only (campaign_forkserver)
    try:
        forkserver.ensure_running()
    finally:
        os.environ.pop(FORKSERVER_MARK, None)
    dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"})


def ros_concurrency(configs, cores, requested=None, available=None):
    """(experiments at a time, note or None) of a ROS campaign on this machine. Default: half
    the cores (at least 1), and no more than the machine's available memory holds of the
    largest memory estimate among ``configs`` (the runs' configuration dicts;
    :func:`patrolling_sim.experiment.validation.memory_parts`). A ``requested`` number is kept; the note
    then says when the estimate does not fit. ``available``: MB (None: read from the
    machine)."""
    figures = {}
    need = 0.0
    for c in configs:
        if c["map"] not in figures:
            figures[c["map"]] = validation.map_memory_figures(c["map"])
        nav = NAV_ALIASES.get(c.get("nav"), c.get("nav"))
        need = max(need, validation.memory_estimate_mb(c["robots"], c.get("processes"),
                                                       *figures[c["map"]], nav))
    avail = validation.available_memory_mb() if available is None else available
    fit = None if not need or avail is None else int(avail // need)
    if requested:
        note = None
        if fit is not None and requested > fit:
            note = (f"warning: --workers {requested}: {requested} experiments at a time need "
                    f"about {requested * need / 1024:.1f} GB (the largest run about "
                    f"{need / 1024:.1f} GB), the machine has {avail / 1024:.1f} GB available")
        return requested, note
    n = max(1, cores // 2)
    if fit is not None and fit < n:
        return max(1, fit), (f"{max(1, fit)} experiment(s) at a time: the largest run needs "
                             f"about {need / 1024:.1f} GB, the machine has "
                             f"{avail / 1024:.1f} GB available")
    return n, None


class _ClusterStart:
    """A LocalCluster (graph mode: one single-threaded worker process per ``n``; ROS mode:
    ``n`` concurrent experiments) started in a background thread. ``result()`` waits for it
    and raises what its start raised; ``result_or_none()`` waits and returns None on an
    error (the caller is already stopping)."""

    def __init__(self, n: int):
        self._cluster = self._error = None
        self._thread = threading.Thread(target=self._start, args=(n,), daemon=True,
                                        name="campaign-cluster-start")
        self._thread.start()

    def _start(self, n):
        try:
            from distributed import LocalCluster
            # dashboard_address ":0": the scheduler's HTTP server (started even without a
            # dashboard) takes a free port; its default, 8787, is taken if another campaign
            # runs, and Dask then warns "Perhaps you already have a cluster running?"
            self._cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                         dashboard_address=":0", silence_logs=30,
                                         resources={"experiment": 1})
        except BaseException as e:            # handed to the caller by result()
            self._error = e

    def result(self):
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._cluster

    def result_or_none(self):
        self._thread.join()
        return self._cluster


def _map(client, fn, *iterables, **kw):
    """``client.map(fn, *iterables, pure=False, **kw)``, called from this short function on
    purpose: Dask records the source of the function that calls ``map`` (for its dashboard),
    and tokenising ``run_campaign``'s long body took 0.09 s of every campaign's start."""
    return client.map(fn, *iterables, pure=False, **kw)


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
            at least 1, and no more than the memory holds (ROS, :func:`ros_concurrency`).
        retry_failed: also redo crashed runs.
        limit: submit at most this many runs (tests, dry runs).
        on_record: called with each stored record (tests).

    Returns:
        ``{"ran": n, "skipped": n, "interrupted": bool, "table": path}``.
    Ctrl-C (or SIGTERM) stops cleanly: runs in progress are cancelled, every finished run's
    files and record are complete, and the next call resumes.
    """
    t_start = time.monotonic()
    os.makedirs(out, exist_ok=True)
    write_atomic(os.path.join(out, "campaign.yaml"), yaml.safe_dump(campaign.raw,
                                                                    sort_keys=False))
    state = load_state(out)
    todo = [r for r in campaign.runs if needs_run(state.get(r.key), retry_failed)]
    skipped = len(campaign.runs) - len(todo)
    if limit is not None:
        todo = todo[:limit]
    if todo and not scheduler:
        _env_for_workers()                     # the workers' forkserver imports meanwhile
    from distributed import Client, wait
    started = datetime.datetime.now(datetime.timezone.utc)
    prov = {"name": campaign.name, "mode": campaign.mode, "file": campaign.path,
            "runs": len(campaign.runs), "code": campaign.code, "client_host": socket.gethostname(),
            "python": platform.python_version(), "packages": None,
            "start": started.isoformat(timespec="seconds")}
    interrupted = {"sig": None}
    ran = 0
    t_submit = t_last = None                   # runs submitted; last run stored (monotonic)
    cluster = client = starting = None
    dropped = []                               # what the version check skips, to restore

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
        cores = os.cpu_count() or 1
        if todo and not scheduler:
            # the LocalCluster starts in a thread: its worker processes start and import on
            # the other core(s) while this process does its own preparation below
            if campaign.mode == "graph":
                size = workers or cores
            else:
                size, note = ros_concurrency([r.config for r in todo], cores, workers)
                if note:
                    stream.write(f"campaign {campaign.name}: {note}\n")
            # every party of the LocalCluster is ours: its version check need not import
            # pandas (campaign_forkserver.drop_unused_version_checks; its workers' server
            # did the same)
            dropped = drop_unused_version_checks()
            starting = _ClusterStart(size)
        prov["packages"] = _package_versions()
        if not todo:
            stream.write(f"campaign {campaign.name}: {len(campaign.runs)} runs, {skipped} already "
                         "done, 0 to run\n")
        if todo:
            if scheduler:
                client = Client(scheduler, timeout="30s")
            else:
                cluster = starting.result()
                client = Client(cluster)
                # our workers let a signal to the process group pass: the campaign stops
                # them (campaign_tasks.IgnoreGroupSignals)
                client.register_worker_plugin(IgnoreGroupSignals(), name="ignore-group-signals")
            link = getattr(client, "dashboard_link", None)
            stream.write(f"campaign {campaign.name}: {len(campaign.runs)} runs, {skipped} already "
                         f"done, {len(todo)} to run on {len(client.scheduler_info()['workers'])} "
                         f"worker(s)" + (f"; dashboard {link}" if link and cluster is None
                                        else "") + "\n")
            n_workers = max(1, len(client.scheduler_info()["workers"]))
            # one map() call: Dask inspects the caller's source once per call, not per run.
            # Graph runs go in chunks (several runs per task, see campaign_tasks.chunks);
            # each future stands for a list of runs.
            if campaign.mode == "graph":
                groups, i = [], 0
                for size in chunks(len(todo), n_workers):
                    groups.append(todo[i:i + size])
                    i += size
                flist = _map(client, run_graph_chunk, [[r.config for r in g] for g in groups])
            else:
                groups = [[r] for r in todo]
                flist = _map(client, run_ros_task, [r.config for r in todo],
                             [paths.data_root()] * len(todo),
                             resources={"experiment": 1} if cluster else None)
            futs = dict(zip(flist, groups))
            t_submit = time.monotonic()
            progress = _Progress(len(todo), skipped, stream)
            next_free = {}                      # result prefix -> first suffix to test
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
                    group = futs.pop(fut)
                    try:
                        results = fut.result()
                        if campaign.mode != "graph":
                            results = [results]
                    except Exception as e:         # the task raised: record it, go on
                        results = [{"status": "ERROR", "error": f"{type(e).__name__}: {e}"}
                                   ] * len(group)
                    for spec, result in zip(group, results):
                        rec = store_result(out, spec, result, campaign, next_free)
                        state[spec.key] = rec
                        ran += 1
                        t_last = time.monotonic()
                        progress.update(rec, min(len(pending), n_workers))
                        if on_record:
                            on_record(rec)
                    if interrupted["sig"] is not None:
                        break
            collecting["on"] = False
            if interrupted["sig"] is not None and pending:
                raise KeyboardInterrupt
            if progress.tty:
                stream.write("\n")
    except KeyboardInterrupt:
        stream.write(f"\ncampaign {campaign.name}: interrupted after {ran} run(s); run the same "
                     "command again to resume\n")
    finally:
        # a signal from here on only sets the flag: the cluster is stopped and the table and
        # provenance written whatever arrives
        collecting["on"] = True
        try:
            if starting is not None and cluster is None:
                cluster = starting.result_or_none()    # interrupted while it was starting
            # a worker busy with a run is killed after a few seconds when the cluster
            # closes: expected after an interruption (its runs are recorded as not run), so
            # Dask's warning about it is not shown; the level is restored afterwards
            # (nor the scheduler's warning about such a worker's late heartbeat; the worker's
            # own records of it are dropped by campaign_tasks.SchedulerGoneFirst)
            quiet = [logging.getLogger(n) for n in ("distributed.nanny", "distributed.scheduler")]
            levels = [q.level for q in quiet]
            if interrupted["sig"] is not None:
                for q in quiet:
                    q.setLevel(logging.ERROR)
            for closing in (client, cluster):
                if closing is not None:
                    try:
                        closing.close()
                    except Exception:
                        pass
            for q, level in zip(quiet, levels):   # this process may run another campaign
                q.setLevel(level)
            restore_version_checks(dropped)
            table = write_table(out, campaign, state)
            # a signal that came once every run was stored interrupted nothing
            stopped = interrupted["sig"] is not None and ran < len(todo)
            if interrupted["sig"] is not None and not stopped:
                stream.write(f"campaign {campaign.name}: signal received after the last run: "
                             "finished\n")
            prov["end"] = datetime.datetime.now(datetime.timezone.utc).isoformat(
                timespec="seconds")
            prov["interrupted"] = stopped
            # where this call's time went: the engine's start (cluster or connection, until
            # the runs were submitted), then the runs (until the last one was stored), so
            # that throughput is measured without the start (bench/campaign_bench.py)
            prov["timing"] = {
                "engine_start_s": None if t_submit is None else round(t_submit - t_start, 3),
                "runs_s": None if t_last is None else round(t_last - t_submit, 3),
                "runs_stored": ran}
            write_atomic(os.path.join(out, "provenance.yaml"),
                          yaml.safe_dump(prov, sort_keys=False))
        finally:
            for s, h in old.items():
                signal.signal(s, h)
    return {"ran": ran, "skipped": skipped, "interrupted": stopped,
            "signal": interrupted["sig"] if stopped else None, "table": table}


#: provenance: the packages whose versions a campaign records (module name: distribution)
PROVENANCE_PACKAGES = {"numpy": "numpy", "scipy": "scipy", "networkx": "networkx",
                       "pandas": "pandas", "dask": "dask", "distributed": "distributed",
                       "yaml": "PyYAML"}


def _package_versions():
    """Versions of PROVENANCE_PACKAGES from the installed packages' metadata (importing them
    to read ``__version__`` cost the campaign's start-up 0.3-0.4 s); a package without
    metadata is imported, one that cannot be imported is None."""
    from importlib import metadata
    out = {}
    for mod, dist in PROVENANCE_PACKAGES.items():
        try:
            out[mod] = metadata.version(dist)
        except Exception:
            try:
                out[mod] = str(__import__(mod).__version__)
            except Exception:
                out[mod] = None
    return out


def main(argv=None):

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
        if not a.scheduler and not a.dry_run and os.path.isfile(a.campaign):
            # a LocalCluster is likely: its workers' forkserver starts importing now, on the
            # other core, while this process imports the simulator to validate the campaign
            # (0.15-0.2 s sooner than from run_campaign; if the file turns out to be bad, or
            # nothing is left to run, the server just exits with this process)
            _env_for_workers()
        camp = load_campaign(a.campaign)
        for line in camp.warnings:
            sys.stderr.write(f"campaign.py: warning: {line}\n")
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
            per_run = len(camp.runs) <= REPORT_RUN_PLOTS_MAX
            try:
                build_report([os.path.join(out, RESULTS_DIR)], os.path.join(out, "report"),
                             run_plots=per_run)
                print(f"report: {os.path.join(out, 'report', 'report.html')}"
                      + ("" if per_run else f" (no per-run time plots: {len(camp.runs)} runs "
                         f"> {REPORT_RUN_PLOTS_MAX}; scripts/report.py "
                         f"{os.path.join(out, RESULTS_DIR)} draws them)"))
            except Exception as e:             # the table is the product; say why no report
                print(f"campaign.py: warning: no report ({type(e).__name__}: {e})")
        if res["interrupted"]:
            return 130 if res["signal"] == signal.SIGINT else 143
        return 0
    return run_main(_main, "campaign.py", argv)
