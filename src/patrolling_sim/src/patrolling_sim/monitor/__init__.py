"""What the monitor measures and writes, without ROS.

- :mod:`~patrolling_sim.monitor.core`       -- the monitor's metrics: idleness, visits, cycles,
  interference
- :mod:`~patrolling_sim.monitor.results`    -- the four result files and the run's file prefix
- :mod:`~patrolling_sim.monitor.run_status` -- run statuses and ``_run.yaml``
- :mod:`~patrolling_sim.monitor.metrics`    -- metrics beyond the original's, from the visit log
"""
