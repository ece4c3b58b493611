#!/usr/bin/python3
"""Inspect, validate, draw and convert maps and patrol graphs (see --help)."""

import early_signal

early_signal.require("graph_tool.py")

from patrolling_sim.extraction.graph_tool import entry

entry()
