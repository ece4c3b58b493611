"""Patrolling algorithms: one module per algorithm, registered by short name.

Discovery is the only registration step: importing this package imports every module of
the package's directory (``pkgutil``), and each module's ``@register`` classes enter
:data:`REGISTRY`. Adding an algorithm therefore means dropping one file here; every entry
point (ROS agent, graph mode, runner, GUI, report) reads the same registry. A module that
fails to import is skipped with a one-line warning naming its file.

See :mod:`patrolling_sim.algorithms.base` for the strategy API and ``docs/protocol.md`` for
the life cycle that calls it.
"""
import importlib
import logging
import os
import pkgutil

from patrolling_sim.algorithms.base import (REGISTRY, Driver, PatrolStrategy, StrategyContext,
                                            argmax_random, create, names, register)

#: the strategy API (defined in :mod:`patrolling_sim.algorithms.base`) and the registry
__all__ = ["REGISTRY", "Driver", "PatrolStrategy", "StrategyContext", "argmax_random", "create",
           "discover", "names", "register"]

_log = logging.getLogger(__name__)
#: modules already imported by :func:`discover` (name -> file), and those that failed
loaded = {}
failed = {}


def discover():
    """Import every not-yet-imported module of this package (names not starting with
    ``_``); returns the registry. Safe to call again, e.g. after extending ``__path__``."""
    for mod in pkgutil.iter_modules(__path__):
        if mod.name.startswith("_") or mod.name in loaded or mod.name in failed:
            continue
        path = os.path.join(getattr(mod.module_finder, "path", ""), mod.name + ".py")
        try:
            importlib.import_module(f"{__name__}.{mod.name}")
        except Exception as e:       # a broken user module must not stop the others
            failed[mod.name] = path
            msg = str(e).splitlines()[0] if str(e) else ""
            _log.warning("warning: algorithm module %s not loaded: %s%s", path,
                         type(e).__name__, f": {msg}" if msg else "")
            continue
        loaded[mod.name] = path
    return REGISTRY


discover()
