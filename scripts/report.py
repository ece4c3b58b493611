#!/usr/bin/python3
"""Analyse patrolling results into an HTML report, CSV tables and PNG figures (see --help
and docs/report.md)."""

import early_signal

early_signal.require("report.py", ("pandas", "matplotlib", "scipy"))

from patrolling_sim.report.cli import entry

entry()
