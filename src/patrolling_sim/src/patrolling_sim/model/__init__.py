"""The patrol graph and the map it is drawn on.

- :mod:`~patrolling_sim.model.graph`      -- the ``.graph`` format and :class:`PatrolGraph`
- :mod:`~patrolling_sim.model.tables`     -- a graph's precomputed all-pairs tables
- :mod:`~patrolling_sim.model.map_bundle` -- a map's occupancy grid and graph loaded by name
- :mod:`~patrolling_sim.model.draw`       -- drawing a map and its graph (images)
- :mod:`~patrolling_sim.model.dta_params` -- the DTA algorithms' ``.params`` files

Occupancy maps themselves are read by the navigation package's public map loader,
``spqrel_nav_lite.mapio``.
"""
