#!/usr/bin/python3
"""Reference tables (docs/reference/) from a campaign folder's runs.csv (see --help and
docs/campaigns.md)."""
import sys

import early_signal

early_signal.require("reference_docs.py", ("pandas", "matplotlib"))


if __name__ == "__main__":
    from patrolling_sim.report.reference_docs import main
    sys.exit(main())
