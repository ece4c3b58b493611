#!/usr/bin/python3
"""Inspect, validate, draw and convert maps and patrol graphs (see --help)."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.extraction.graph_tool import entry  # noqa: E402

entry()
