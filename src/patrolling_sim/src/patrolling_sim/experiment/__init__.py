"""An experiment's inputs checked before anything starts, the same way in every mode.

- :mod:`~patrolling_sim.experiment.validation` -- map files, team size, memory estimate, start poses
"""
