"""Scenario settings: imperfect communication and robot failures.

- :mod:`~patrolling_sim.scenarios.comm`      -- communication models (``--comm``)
- :mod:`~patrolling_sim.scenarios.attrition` -- failure schedules (``--attrition``)
- :mod:`~patrolling_sim.scenarios.scenario`  -- a run's scenario: checks, ``_scenario.yaml``,
  table columns
"""
