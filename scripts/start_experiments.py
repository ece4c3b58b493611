#!/usr/bin/python3
"""Start multi-robot patrolling experiments: Tk GUI, headless CLI, original positional form,
YAML configurations and batches. See --help and README.md."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.runner.cli import entry  # noqa: E402

entry()
