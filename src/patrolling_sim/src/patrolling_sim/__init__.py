"""patrolling_sim: multi-robot patrolling simulation and benchmarking.

The modules directly under this package form the *pure core*: they import neither rospy
nor any ROS message and can be used (and tested) without a ROS master.

- :mod:`patrolling_sim.graph`         -- ``.graph`` patrol graph reader/writer (networkx)
- :mod:`patrolling_sim.mapio`         -- map_server yaml + image reader (occupancy grid)
- :mod:`patrolling_sim.initial_poses` -- start positions (shipped table or computed)
- :mod:`patrolling_sim.msp_routes`    -- MSP route files
- :mod:`patrolling_sim.dta_params`    -- DTA ``.params`` files
- :mod:`patrolling_sim.paths`         -- where shipped maps and parameters live
"""
__version__ = "0.1.0"
