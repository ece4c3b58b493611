"""Patrolling algorithms: one module per algorithm, registered by short name.

See :mod:`patrolling_sim.algorithms.base` for the strategy API.
"""
from .base import REGISTRY, PatrolStrategy, StrategyContext, Driver, register  # noqa: F401
from .base import argmax_random, create, names  # noqa: F401,E402

# one module per algorithm; importing it registers it (adding one = a file + a line here)
from . import rand, cr, hcr, hpcc, cgg, cgg_tsp, msp, gbs, sebs, cbls, dtag, dtap  # noqa: F401,E402
