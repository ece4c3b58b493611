#!/usr/bin/python3
"""Start multi-robot patrolling experiments: Tk GUI, headless CLI, original positional form,
YAML configurations and batches. See --help and README.md."""
import early_signal  # first: a signal during start-up ends the program at once, in one line

early_signal.install("start_experiments.py")
early_signal.require("start_experiments.py", ("rospy",))


from patrolling_sim.runner.cli import entry

entry()
