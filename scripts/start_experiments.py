#!/usr/bin/python3
"""Start multi-robot patrolling experiments: Tk GUI, headless CLI, original positional form,
YAML configurations and batches. See --help and README.md."""
import early_signal  # first: a signal during start-up ends the program at once, in one line

early_signal.install("start_experiments.py")

import os  # noqa: E402
import sys  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.runner.cli import entry  # noqa: E402

entry()
