"""Imported first by the forkserver of a campaign's LocalCluster workers
(``campaign.WORKER_PRELOAD``): makes that server ignore SIGTERM, and takes pandas out of
Dask's version check in the server and so in the workers forked from it
(:func:`drop_unused_version_checks`).

The server shares the campaign's process group. A SIGTERM sent to the whole group (``kill
-TERM -PGID``, a batch system ending the job) killed it, and each worker's Nanny, which
learns of its worker's exit through the server, then took the live workers for dead and
tried to restart them, printing errors while the campaign was stopping. The server needs no
signal to end: it exits when the campaign process does (its pipe from the campaign closes).
The campaign sets :data:`MARK` in the environment only while it starts the server, so
importing this module anywhere else does nothing. Workers forked from the server inherit
the ignored SIGTERM until the campaign's worker plugin (``campaign_tasks.IgnoreGroupSignals``)
replaces it."""
import os
import signal

#: environment variable set by the campaign while it starts the server
MARK = "PATROLLING_SIM_CAMPAIGN_FORKSERVER"

#: packages that Dask's version check imports only to read their versions
#: (``distributed.versions.optional_packages``) and that a campaign's workers never use
UNUSED_IN_WORKERS = ("pandas",)


def drop_unused_version_checks():
    """Take UNUSED_IN_WORKERS out of the packages Dask imports for its version check; returns
    what was taken out, for :func:`restore_version_checks`.

    A worker imports every package of that list when it registers with the scheduler, and
    the client's Nanny when it starts its first worker, to compare their versions; pandas
    alone is 0.15-0.2 s of a LocalCluster's start, on its critical path twice (the Nanny in
    the client's event-loop thread, then the worker before it registers;
    docs/benchmarks/campaign.md). Graph-mode workers never import pandas, ROS-mode workers
    start the runner as a program of its own, so its version has nothing to check. Applied
    only where every party is the campaign's own (its LocalCluster's client, scheduler and
    workers): the client also running a ``--scheduler`` campaign keeps the full check
    (restored after its LocalCluster closes), since a remote worker would report a pandas
    version the client would lack. The list is a module global of ``distributed.versions``
    (2022.12), changed in place so that every reader sees it; if a Dask release lacks it,
    nothing is changed."""
    try:
        from distributed import versions
    except ImportError:                       # not a Dask process: nothing to check
        return []
    packages = getattr(versions, "optional_packages", None)
    if not isinstance(packages, list):
        return []
    dropped = [p for p in packages
               if isinstance(p, tuple) and p and p[0] in UNUSED_IN_WORKERS]
    packages[:] = [p for p in packages if p not in dropped]
    return dropped


def restore_version_checks(dropped):
    """Put back what :func:`drop_unused_version_checks` took out."""
    if not dropped:
        return
    from distributed import versions
    versions.optional_packages.extend(p for p in dropped
                                      if p not in versions.optional_packages)


if os.environ.pop(MARK, None) == "1":
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    drop_unused_version_checks()             # imports distributed, the server's next preload
