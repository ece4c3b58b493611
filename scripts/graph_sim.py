#!/usr/bin/python3
"""Graph-level patrolling experiments without ROS (see --help)."""
import early_signal  # first: a signal during start-up ends the program at once, in one line

early_signal.install("graph_sim.py")
early_signal.require("graph_sim.py")

import signal
import sys

from patrolling_sim.graphsim.cli import main

signal.signal(signal.SIGINT, signal.default_int_handler)   # from here: KeyboardInterrupt,
signal.signal(signal.SIGTERM, signal.SIG_DFL)             # handled by main (files kept)
sys.exit(main())
