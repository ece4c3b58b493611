"""The PatrolAgent life cycle, shared by graph mode and the ROS nodes.

- :mod:`~patrolling_sim.agent.core`    -- the life cycle (state machine) driving a strategy
- :mod:`~patrolling_sim.agent.faults`  -- its scenario side: the comm model at the receiver,
  failure and repair
- :mod:`~patrolling_sim.agent.factory` -- building a robot's agent: its seed, its strategy and
  comm model
"""
