"""patrolling_sim: multi-robot patrolling simulation and benchmarking.

The modules directly under this package form the *pure core*: they import neither rospy
nor any ROS message and can be used (and tested) without a ROS master.

- :mod:`patrolling_sim.graph`         -- ``.graph`` patrol graph reader/writer (networkx)
- :mod:`patrolling_sim.mapio`         -- map_server yaml + image reader (spqrel_nav_lite.mapio)
- :mod:`patrolling_sim.initial_poses` -- start positions (shipped table or computed)
- :mod:`patrolling_sim.msp_routes`    -- MSP route files
- :mod:`patrolling_sim.dta_params`    -- DTA ``.params`` files
- :mod:`patrolling_sim.paths`         -- where shipped maps and parameters live
"""
__version__ = "0.1.0"

# The core reads maps with the navigation package's loader (spqrel_nav_lite.mapio: one
# loader, and spqrel_nav_lite does not depend on this package). A built workspace puts both
# packages on the Python path (devel/setup.bash); the scripts of a source checkout add only
# this package's folder, so the sibling package's source folder is added when it is missing.
try:
    import spqrel_nav_lite  # noqa: F401
except ImportError:
    import os as _os
    import sys as _sys
    _sys.path.append(_os.path.join(_os.path.dirname(_os.path.abspath(__file__)), "..", "..", "..",
                                   "spqrel_nav_lite", "src"))
    import spqrel_nav_lite  # noqa: F401,E402
