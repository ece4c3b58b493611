#!/usr/bin/python3
"""Campaigns of experiments on Dask, resumable (see --help and docs/campaigns.md)."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))

if __name__ == "__main__":      # Dask's worker processes re-import this file: no side effects
    from patrolling_sim.campaign import main
    sys.exit(main())
