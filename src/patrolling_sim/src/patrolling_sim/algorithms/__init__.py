"""Patrolling algorithms: one module per algorithm, registered by short name.

See :mod:`patrolling_sim.algorithms.base` for the strategy API.
"""
from .base import REGISTRY, PatrolStrategy, StrategyContext, Driver, register  # noqa: F401
