"""The Dask cluster a campaign runs on: its workers' environment and forkserver, the number
of ROS experiments at a time, a LocalCluster started in a background thread and closed
quietly. Part of :mod:`patrolling_sim.campaign.engine` (see docs/campaigns.md)."""
import logging
import multiprocessing
import os
import threading
from multiprocessing import forkserver

from patrolling_sim.campaign.forkserver import MARK as FORKSERVER_MARK
from patrolling_sim.common import paths
from patrolling_sim.experiment import validation
from patrolling_sim.runner.config import NAV_ALIASES

#: Dask settings of the LocalCluster's workers: no statistical profiler (it samples the
#: running task's stack every 10 ms, which costs a simulation run several per cent) and a
#: slower event-loop watchdog; passed as environment variables, set before the workers'
#: forkserver starts, so the workers see them
WORKER_DASK_ENV = {"DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False",
                   "DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL": "1s"}


#: what the forkserver of the LocalCluster's workers imports once, before it forks them
#: (campaign_forkserver first: it makes the server ignore a SIGTERM sent to the process group)
WORKER_PRELOAD = ["patrolling_sim.campaign.forkserver", "distributed",
                  "patrolling_sim.campaign.tasks", "patrolling_sim.graphsim.simulator"]


def env_for_workers():
    """Make the workspace's packages importable in worker processes started from here, with
    the settings of WORKER_DASK_ENV, and start their forkserver.

    The workers are forked from a server process that has imported WORKER_PRELOAD once,
    not spawned (Dask's default, where each worker starts an interpreter and imports
    ``distributed`` and the simulator itself): the server starts here (from the command
    line's ``main`` before the campaign file is validated; called again from
    ``run_campaign``, it finds the server running), before this process imports
    ``distributed``, and imports on the other core while this process prepares, so the
    cluster's start does not wait for the workers' imports, and two workers import once
    (bench/notes/campaign.md). A forked worker gets the server's environment, so Dask's
    ``pre-spawn-environ`` (which it sets just before spawning) is set here first. Also sets
    Dask's ``distributed.worker.multiprocessing-method`` to ``forkserver``."""
    src = paths.package_parent()
    pp = os.environ.get("PYTHONPATH", "")
    if src not in pp.split(os.pathsep):
        os.environ["PYTHONPATH"] = src + (os.pathsep + pp if pp else "")
    for k, v in WORKER_DASK_ENV.items():
        os.environ.setdefault(k, v)
    import dask
    dask.config.refresh()
    for k, v in (dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {}).items():
        os.environ.setdefault(k, str(v))
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
    :func:`patrolling_sim.experiment.validation.memory_parts`). A ``requested`` number is
    kept; the note then says when the estimate does not fit. ``available``: MB (None: read
    from the machine)."""
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


def local_cluster_size(mode, configs, workers, cores):
    """(size, note or None) of the LocalCluster of a campaign in ``mode`` whose runs to do
    have the configuration dicts ``configs``: graph mode, ``workers`` or else ``cores`` (no
    note); ROS mode, :func:`ros_concurrency` with ``workers`` as the requested number."""
    if mode == "graph":
        return workers or cores, None
    return ros_concurrency(configs, cores, workers)


class ClusterStart:
    """A LocalCluster (graph mode: one single-threaded worker process per ``n``; ROS mode:
    ``n`` concurrent experiments) started in a background thread (named
    ``campaign-cluster-start``). ``result()`` waits for it and raises what its start
    raised; ``result_or_none()`` waits and returns None on an error (the caller is already
    stopping)."""

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
        """The started LocalCluster; raises what its start raised."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._cluster

    def result_or_none(self):
        """The started LocalCluster, or None if its start failed."""
        self._thread.join()
        return self._cluster


def close_quietly(client, cluster, interrupted):
    """Close ``client`` then ``cluster`` (either may be None; an error while closing is
    ignored). With ``interrupted``, Dask's warnings about the workers still busy with a run
    (killed after a few seconds when the cluster closes: expected, their runs are recorded
    as not run) and about such a worker's late heartbeat are not shown: the loggers
    ``distributed.nanny`` and ``distributed.scheduler`` are set to ERROR while closing and
    get their levels back afterwards (this process may run another campaign). The worker's
    own records of it are dropped by campaign_tasks.SchedulerGoneFirst."""
    quiet = [logging.getLogger(n) for n in ("distributed.nanny", "distributed.scheduler")]
    levels = [q.level for q in quiet]
    if interrupted:
        for q in quiet:
            q.setLevel(logging.ERROR)
    for closing in (client, cluster):
        if closing is not None:
            try:
                closing.close()
            except Exception:
                pass
    for q, level in zip(quiet, levels):
        q.setLevel(level)
