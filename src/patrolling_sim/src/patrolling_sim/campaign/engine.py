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
(:class:`~patrolling_sim.graphsim.config.GraphSimConfig` for graph mode,
:class:`~patrolling_sim.runner.config.ExperimentConfig` for ROS mode), so a key added to
either is available to campaigns at once. Every run is validated before anything starts.

Every run has a stable *key*: a hash of its mode, its full configuration (defaults
included; a file its algorithm reads, as POLICY's policy file, by its content:
:func:`~patrolling_sim.campaign.spec.keyed_config`) and the code version (git commit). The
campaign folder keeps one state record per run (``state/<key>.yaml``); re-running the same
command skips runs that ended normally (TIMEOUT, CYCLES, FAIL), redoes incomplete ones
(interrupted, aborted, never finished) and, with ``retry_failed``, crashed ones. Results
travel back through Dask (no shared file system) and only the client writes files: the
usual result files in the usual tree under ``results/``, plus ``<prefix>_visits.csv`` and
``<prefix>_metrics.yaml`` (:mod:`patrolling_sim.monitor.metrics`), and ``runs.csv``, one
row per run. See ``docs/campaigns.md``.

The cluster (its start, its size, its workers' forkserver) is in
:mod:`~patrolling_sim.campaign.cluster`, the ``campaign.py`` command line in
:mod:`~patrolling_sim.campaign.cli`.
"""
import asyncio
import contextlib
import datetime
import os
import platform
import signal
import socket
import sys
import time
from importlib import metadata
from typing import Callable, Optional

import yaml

from patrolling_sim.common import paths
from patrolling_sim.campaign.cluster import (ClusterStart, close_quietly, env_for_workers,
                                             local_cluster_size)
from patrolling_sim.campaign.spec import DONE_STATUSES, Campaign
from patrolling_sim.campaign.store import (damaged, load_state, needs_run, store_result,
                                           write_atomic, write_table)
from patrolling_sim.campaign.tasks import IgnoreGroupSignals, chunks, run_graph_chunk, run_ros_task


class _Progress:
    """Progress of a campaign: a bar redrawn in place on a terminal, lines in a log. Shown at
    most every TTY_INTERVAL (terminal) or LOG_INTERVAL (log) seconds, so that thousands of
    10-ms graph runs do not write thousands of lines to a log; a failed run and the last run
    are always shown, and ROS runs, minutes apart, each get their line."""

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
        """Count the stored run ``record`` (failed unless its status is in DONE_STATUSES) and
        show the progress if it is due; ``running``: runs in progress, for the line."""
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


def _map(client, fn, *iterables, **kw):
    """``client.map(fn, *iterables, pure=False, **kw)``, called from this short function on
    purpose: Dask records and tokenises the source of the function that calls ``map`` (for
    its dashboard), which for a long caller is a cost of every campaign's start."""
    return client.map(fn, *iterables, pure=False, **kw)


def _provenance(campaign):
    """The provenance record of a campaign run starting now (``provenance.yaml``): name,
    mode, file, run count, code version, client host, Python version and start time;
    ``packages`` is None until the caller sets it."""
    started = datetime.datetime.now(datetime.timezone.utc)
    return {"name": campaign.name, "mode": campaign.mode, "file": campaign.path,
            "runs": len(campaign.runs), "code": campaign.code,
            "client_host": socket.gethostname(), "python": platform.python_version(),
            "packages": None, "start": started.isoformat(timespec="seconds")}


class _CampaignRun:
    """The state of one :func:`run_campaign` call and its steps: the runs to do, the
    cluster and client, the signal received, the runs stored, the provenance record."""

    def __init__(self, campaign, out, retry_failed, limit, stream, on_record):
        """Create the folder ``out``, write its ``campaign.yaml``, load its state records and
        pick the runs to do (those :func:`needs_run` selects, at most ``limit``)."""
        self.campaign, self.out, self.stream, self.on_record = campaign, out, stream, on_record
        os.makedirs(out, exist_ok=True)
        write_atomic(os.path.join(out, "campaign.yaml"), yaml.safe_dump(campaign.raw,
                                                                        sort_keys=False))
        self.state = load_state(out)
        self.redone = self._damaged_runs()
        self.todo = [r for r in campaign.runs if needs_run(self.state.get(r.key), retry_failed)]
        self.skipped = len(campaign.runs) - len(self.todo)
        if limit is not None:
            self.todo = self.todo[:limit]
        self.sig = None                        # the signal received (SIGINT, SIGTERM) or None
        self.collecting = False                # see on_signal
        self.ran = 0
        self.t_submit = self.t_last = None     # runs submitted; last run stored (monotonic)
        self.cluster = self.client = self.starting = None
        self.prov = None

    def _damaged_runs(self):
        """Forget the records of finished runs whose files no longer match them
        (:func:`patrolling_sim.campaign.store.damaged`), so they are run again; their
        remaining files are removed. Returns how many; each is reported on the stream."""
        count = 0
        for r in self.campaign.runs:
            rec = self.state.get(r.key)
            if not rec or rec.get("status") not in DONE_STATUSES:
                continue
            why = damaged(self.out, rec)
            if why is None:
                continue
            for rel in (rec.get("files") or {}):
                with contextlib.suppress(OSError):
                    os.remove(os.path.join(self.out, rel))
            del self.state[r.key]
            count += 1
            self.stream.write(f"campaign {self.campaign.name}: {r.label()}: {why}: "
                              "run again\n")
        return count

    def on_signal(self, signum, _frame):
        """Handler of SIGINT and SIGTERM: records the signal. While results are being
        collected (``collecting``) that is all: the flag is checked between two stored runs,
        so a run's files and record are never cut half-way; otherwise it raises
        KeyboardInterrupt at once. Python runs the handler in the main thread whichever
        thread the signal hit, so the flag is the only safe way with Dask's threads around."""
        self.sig = signum
        if not self.collecting:
            raise KeyboardInterrupt

    def start_cluster(self, workers):
        """Start a LocalCluster for the runs to do in a background thread (``starting``),
        sized by :func:`local_cluster_size` (its note, if any, is written to the stream):
        its worker processes start and import on the other core(s) while this process does
        its own preparation."""
        cores = os.cpu_count() or 1
        size, note = local_cluster_size(self.campaign.mode, [r.config for r in self.todo],
                                        workers, cores)
        if note:
            self.stream.write(f"campaign {self.campaign.name}: {note}\n")
        self.starting = ClusterStart(size)

    def connect(self, client_cls, scheduler):
        """Connect a ``client_cls`` (:class:`distributed.Client`) to ``scheduler`` or else to
        the started LocalCluster (whose workers then let a signal to the process group pass:
        the campaign stops them, campaign_tasks.IgnoreGroupSignals), write the campaign's
        first line and return the number of workers (at least 1)."""
        if scheduler:
            self.client = client_cls(scheduler, timeout="30s")
        else:
            self.cluster = self.starting.result()
            self.client = client_cls(self.cluster)
            self.client.register_worker_plugin(IgnoreGroupSignals(), name="ignore-group-signals")
        c, link = self.campaign, getattr(self.client, "dashboard_link", None)
        self.stream.write(f"campaign {c.name}: {len(c.runs)} runs, {self.skipped} already "
                          f"done, {len(self.todo)} to run on "
                          f"{len(self.client.scheduler_info()['workers'])} worker(s)"
                          + (f"; dashboard {link}" if link and self.cluster is None else "")
                          + "\n")
        return max(1, len(self.client.scheduler_info()["workers"]))

    def submit(self, n_workers):
        """Submit the runs to do in one ``map`` call (Dask inspects the caller's source once
        per call, not per run) and return {future: the list of its RunSpecs}: graph runs go
        in chunks of several runs per task (campaign_tasks.chunks), a ROS run is one task
        holding one "experiment" resource on a LocalCluster. Sets ``t_submit``."""
        todo = self.todo
        if self.campaign.mode == "graph":
            groups, i = [], 0
            for size in chunks(len(todo), n_workers):
                groups.append(todo[i:i + size])
                i += size
            flist = _map(self.client, run_graph_chunk, [[r.config for r in g] for g in groups])
        else:
            groups = [[r] for r in todo]
            flist = _map(self.client, run_ros_task, [r.config for r in todo],
                         [paths.program("start_experiments.py")] * len(todo),
                         resources={"experiment": 1} if self.cluster else None)
        futs = dict(zip(flist, groups))
        self.t_submit = time.monotonic()
        return futs

    def collect(self, futs, n_workers, wait):
        """Store the results of ``futs`` (from :meth:`submit`) as they come, with ``wait``
        (:func:`distributed.wait`), showing the progress, until all are stored or a signal
        came; in that case, with runs left, raises KeyboardInterrupt (every stored run's
        files and record complete)."""
        progress = _Progress(len(self.todo), self.skipped, self.stream)
        next_free = {}                          # result prefix -> first suffix to test
        self.collecting = True
        pending = list(futs)
        while pending and self.sig is None:
            try:
                ready = wait(pending, timeout=0.5, return_when="FIRST_COMPLETED").done
            except (TimeoutError, asyncio.TimeoutError):
                continue
            ready = [f for f in pending if f in ready]
            for fut in ready:
                pending.remove(fut)
                self.store(fut, futs.pop(fut), next_free, progress,
                           min(len(pending), n_workers))
                if self.sig is not None:
                    break
        self.collecting = False
        if self.sig is not None and pending:
            raise KeyboardInterrupt
        if progress.tty:
            self.stream.write("\n")

    def store(self, fut, group, next_free, progress, running):
        """Store the results of the finished future ``fut`` for its RunSpecs ``group``
        (each an ERROR record if the task raised), update ``state``, ``ran``, ``t_last`` and
        ``progress`` (``running``: runs in progress) and call ``on_record`` on each record.
        ``next_free``: :func:`store_result`'s cache of result prefixes."""
        try:
            results = fut.result()
            if self.campaign.mode != "graph":
                results = [results]
        except Exception as e:         # the task raised: record it, go on
            results = [{"status": "ERROR", "error": f"{type(e).__name__}: {e}"}] * len(group)
        for spec, result in zip(group, results):
            rec = store_result(self.out, spec, result, self.campaign, next_free)
            self.state[spec.key] = rec
            self.ran += 1
            self.t_last = time.monotonic()
            progress.update(rec, running)
            if self.on_record:
                self.on_record(rec)

    def finish(self, t_start):
        """Stop the cluster (waiting for one still starting) and the client, write
        ``runs.csv`` and ``provenance.yaml`` (with the timing of this call, started at
        ``t_start``: the engine's start until the runs were submitted, then the runs until
        the last one was stored). Returns (table path, stopped): stopped is
        true when a signal came before every run to do was stored."""
        if self.starting is not None and self.cluster is None:
            self.cluster = self.starting.result_or_none()    # interrupted while it was starting
        close_quietly(self.client, self.cluster, self.sig is not None)
        table = write_table(self.out, self.campaign, self.state)
        # a signal that came once every run was stored interrupted nothing
        stopped = self.sig is not None and self.ran < len(self.todo)
        if self.sig is not None and not stopped:
            self.stream.write(f"campaign {self.campaign.name}: signal received after the last "
                              "run: finished\n")
        prov = self.prov
        prov["end"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        prov["interrupted"] = stopped
        t_submit, t_last = self.t_submit, self.t_last
        prov["timing"] = {
            "engine_start_s": None if t_submit is None else round(t_submit - t_start, 3),
            "runs_s": None if t_last is None else round(t_last - t_submit, 3),
            "runs_stored": self.ran}
        write_atomic(os.path.join(self.out, "provenance.yaml"),
                     yaml.safe_dump(prov, sort_keys=False))
        return table, stopped


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
            at least 1, and no more than the memory holds (ROS,
            :func:`patrolling_sim.campaign.cluster.ros_concurrency`).
        retry_failed: also redo crashed runs.
        limit: submit at most this many runs (tests, dry runs).
        on_record: called with each stored record (tests).

    Returns:
        dict: ``ran`` and ``skipped`` (run counts), ``redone`` (finished runs whose files
        no longer matched their records, run again), ``interrupted`` (bool), ``signal`` (the
        signal number or None), ``table`` (the path of ``runs.csv``) and ``state`` (the
        folder's state records by run key, this call's included).

    Ctrl-C (or SIGTERM) stops cleanly: runs in progress are cancelled, every finished run's
    files and record are complete, and the next call resumes.
    """
    t_start = time.monotonic()
    run = _CampaignRun(campaign, out, retry_failed, limit, stream, on_record)
    if run.todo and not scheduler:
        env_for_workers()                      # the workers' forkserver imports meanwhile
    from distributed import Client, wait
    run.prov = _provenance(campaign)
    old = {s: signal.signal(s, run.on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        if run.todo and not scheduler:
            run.start_cluster(workers)
        run.prov["packages"] = _package_versions()
        if not run.todo:
            stream.write(f"campaign {campaign.name}: {len(campaign.runs)} runs, {run.skipped} "
                         "already done, 0 to run\n")
        else:
            n_workers = run.connect(Client, scheduler)
            run.collect(run.submit(n_workers), n_workers, wait)
    except KeyboardInterrupt:
        stream.write(f"\ncampaign {campaign.name}: interrupted after {run.ran} run(s); run the "
                     "same command again to resume\n")
    finally:
        # a signal from here on only sets the flag: the cluster is stopped and the table and
        # provenance written whatever arrives
        run.collecting = True
        try:
            table, stopped = run.finish(t_start)
        finally:
            for s, h in old.items():
                signal.signal(s, h)
    return {"ran": run.ran, "skipped": run.skipped, "redone": run.redone,
            "interrupted": stopped, "signal": run.sig if stopped else None, "table": table,
            "state": run.state}


#: provenance: the packages whose versions a campaign records (module name: distribution)
PROVENANCE_PACKAGES = {"numpy": "numpy", "scipy": "scipy", "networkx": "networkx",
                       "pandas": "pandas", "dask": "dask", "distributed": "distributed",
                       "yaml": "PyYAML"}


def _package_versions():
    """{module: version or None} of PROVENANCE_PACKAGES, read from the installed packages'
    metadata (without importing them); a package without metadata is imported for its
    ``__version__``, one that cannot be imported is None."""
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
