#!/usr/bin/python3
"""Analyse patrolling results into an HTML report, CSV tables and PNG figures (see --help
and docs/report.md)."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.report.cli import entry  # noqa: E402

entry()
