"""Imported first by the forkserver of a campaign's LocalCluster workers
(:data:`patrolling_sim.campaign.cluster.WORKER_PRELOAD`): makes that server ignore SIGTERM.

The server shares the campaign's process group. A SIGTERM sent to the whole group (``kill
-TERM -PGID``, a batch system ending the job) killed it, and each worker's Nanny, which
learns of its worker's exit through the server, then took the live workers for dead and
tried to restart them, printing errors while the campaign was stopping. The server needs no
signal to end: it exits when the campaign process does (its pipe from the campaign closes).
The campaign sets :data:`MARK` in the environment only while it starts the server, so
importing this module anywhere else does nothing. Workers forked from the server inherit
the ignored SIGTERM until the campaign's worker plugin
(:class:`patrolling_sim.campaign.tasks.IgnoreGroupSignals`) replaces it."""
import os
import signal

#: environment variable set by the campaign while it starts the server
MARK = "PATROLLING_SIM_CAMPAIGN_FORKSERVER"

if os.environ.pop(MARK, None) == "1":
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
