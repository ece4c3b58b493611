"""Experiment runner: configuration, launch-file generation, supervision of one run
(own ROS master, orderly shutdown, only its own processes), batches, GUI and videos."""
