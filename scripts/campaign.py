#!/usr/bin/python3
"""Campaigns of experiments on Dask, resumable (see --help and docs/campaigns.md)."""
import os
import signal
import sys


def _early_signal(signum, frame):
    # a signal while the modules load ends the program at once, in one line (nothing written
    # yet); run_campaign installs its own handlers, which stop between two stored runs
    sys.stderr.write(f"campaign.py: interrupted by {signal.Signals(signum).name} before the "
                     "campaign started\n")
    sys.stderr.flush()
    os._exit(143 if signum == signal.SIGTERM else 130)


if __name__ == "__main__":      # Dask's worker processes re-import this file: no side effects
    signal.signal(signal.SIGINT, _early_signal)
    signal.signal(signal.SIGTERM, _early_signal)
    import early_signal
    early_signal.require("campaign.py", ("distributed",))
    from patrolling_sim.campaign.cli import main
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    rc = main()
    # Everything is written and closed. The interpreter's last garbage collections would
    # only walk the objects of numpy, pandas, networkx and distributed before the process
    # ends (part of a campaign command's fixed cost, bench/notes/campaign.md): freezing
    # them skips that; exit handlers and finalizers still run.
    import gc
    gc.freeze()
    sys.exit(rc)
