#!/usr/bin/python3
"""Graph-level patrolling experiments without ROS (see --help)."""
import signal
import sys


def _early_signal(signum, frame):
    # a signal while the modules load ends the program at once, in one line: nothing has
    # been written yet; graph_sim.main installs its own handlers (which keep measured files)
    sys.stderr.write(f"graph_sim.py: interrupted by {signal.Signals(signum).name} before the "
                     "run started\n")
    sys.stderr.flush()
    import os
    os._exit(143 if signum == signal.SIGTERM else 130)


signal.signal(signal.SIGINT, _early_signal)
signal.signal(signal.SIGTERM, _early_signal)

import os  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.graph_sim import main  # noqa: E402

signal.signal(signal.SIGINT, signal.default_int_handler)   # from here: KeyboardInterrupt,
signal.signal(signal.SIGTERM, signal.SIG_DFL)             # handled by main (files kept)
sys.exit(main())
