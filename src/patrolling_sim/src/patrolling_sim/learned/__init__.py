"""Learned policies without any learning library (docs/learning.md): what the learning
environment (:mod:`patrolling_sim.envs`) and the ``POLICY`` strategy
(:mod:`patrolling_sim.algorithms.policy`) share, in plain numpy, so that a trained policy
acts through the very observation code it was trained with.

- :mod:`~patrolling_sim.learned.beliefs`    -- what each robot believes (visits, teammates)
- :mod:`~patrolling_sim.learned.observe`    -- graph tables, flat / graph observations, state
- :mod:`~patrolling_sim.learned.slots`      -- the slot observation (any map, any team size)
- :mod:`~patrolling_sim.learned.policyfile` -- policy files (.npz): loading, checks, inference
"""
