#!/usr/bin/python3
"""Reference tables (docs/reference/) from a campaign folder's runs.csv (see --help and
docs/campaigns.md)."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))

if __name__ == "__main__":
    from patrolling_sim.report.reference_docs import main
    sys.exit(main())
