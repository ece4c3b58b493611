"""Patrol graphs extracted from occupancy grids.

- :mod:`~patrolling_sim.extraction.extract`    -- the pipeline
- :mod:`~patrolling_sim.extraction.space`      -- usable free space and its pieces
- :mod:`~patrolling_sim.extraction.skeleton`   -- skeleton, branches, spur pruning
- :mod:`~patrolling_sim.extraction.free_paths` -- free-path edge costs
- :mod:`~patrolling_sim.extraction.cleanup`    -- clean-up of the vertex graph
- :mod:`~patrolling_sim.extraction.coverage`   -- line-of-sight coverage checks
- :mod:`~patrolling_sim.extraction.graph_tool` -- the ``graph_tool.py`` command line
"""
