#!/usr/bin/python3
"""Graph-level patrolling experiments without ROS (see --help)."""
import early_signal  # first: a signal during start-up ends the program at once, in one line

early_signal.install("graph_sim.py")

import os  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.graphsim.cli import main  # noqa: E402

signal.signal(signal.SIGINT, signal.default_int_handler)   # from here: KeyboardInterrupt,
signal.signal(signal.SIGTERM, signal.SIG_DFL)             # handled by main (files kept)
sys.exit(main())
