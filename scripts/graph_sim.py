#!/usr/bin/python3
"""Graph-level patrolling experiments without ROS (see --help)."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.graph_sim import main  # noqa: E402

sys.exit(main())
