"""Routes over a patrol graph, independent of any algorithm's life cycle.

- :mod:`~patrolling_sim.planning.routes`       -- closed tours, 2-opt / Or-opt, balanced partitions
- :mod:`~patrolling_sim.planning.cyclic_route` -- the original's CGG route (a closed walk)
- :mod:`~patrolling_sim.planning.route_detours` -- the CGG route's outbound walk (its detours)
- :mod:`~patrolling_sim.planning.msp_routes`   -- the original's MSP route files
- :mod:`~patrolling_sim.planning.references`   -- theoretical reference idleness of a graph
"""
