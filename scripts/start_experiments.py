#!/usr/bin/python3
"""Start multi-robot patrolling experiments: Tk GUI, headless CLI, original positional form,
YAML configurations and batches. See --help and README.md."""
import signal
import sys


def _early_signal(signum, frame):
    # a signal during start-up (imports, validation) ends the program at once, in one line:
    # nothing has been started or written yet; the runner installs its own handlers later
    name = signal.Signals(signum).name
    sys.stderr.write(f"start_experiments.py: interrupted by {name} before the run started\n")
    sys.stderr.flush()
    import os
    os._exit(143 if signum == signal.SIGTERM else 130)


# also when SIGINT was inherited ignored (`cmd &` in a script)
signal.signal(signal.SIGINT, _early_signal)
signal.signal(signal.SIGTERM, _early_signal)

import os  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src",
                                "patrolling_sim", "src"))
from patrolling_sim.runner.cli import entry  # noqa: E402

entry()
