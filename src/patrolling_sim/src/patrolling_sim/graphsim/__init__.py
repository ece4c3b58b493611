"""Graph mode: a discrete-event world driving the same agents and monitor as ROS mode.

- :mod:`~patrolling_sim.graphsim.config`    -- :class:`GraphSimConfig`, a run's settings
- :mod:`~patrolling_sim.graphsim.simulator` -- :class:`GraphSimulator`, the event loop
- :mod:`~patrolling_sim.graphsim.motion`    -- robots moving along graph edges
- :mod:`~patrolling_sim.graphsim.feedback`  -- goal outcomes and interference
- :mod:`~patrolling_sim.graphsim.cli`       -- the ``graph_sim.py`` command line
"""
