"""Batch files for ``start_experiments.py --batch FILE``.

A batch file is YAML in one of two shapes:

1. a list of configurations (each a mapping with the keys of
   :mod:`patrolling_sim.runner.config`)::

       - {map: grid, robots: 4, alg: CGG, timeout: 300}
       - {map: grid, robots: 4, alg: SEBS, timeout: 300}

2. a grid: ``base`` (common keys) and ``grid`` (key -> list of values); the cartesian
   product of the grid's lists, in file order, expands into the list::

       base: {map: grid, loc: fake_localization, timeout: 300}
       grid: {alg: [CR, CGG, SEBS], robots: [2, 4], seed: [1, 2, 3]}   # 18 runs
"""
import itertools

from ..errors import PatrolInputError
from ..textfile import read_yaml
from .config import ExperimentConfig


def load_batch(path, base=None):
    """Return the list of ExperimentConfig (not yet validated) described by ``path``."""
    return expand_batch(read_yaml(path, "batch file"), path, base)


def expand_batch(data, source="batch", base=None):
    base_cfg = base or ExperimentConfig()
    if isinstance(data, list):
        entries = data
    elif isinstance(data, dict) and "grid" in data:
        unknown = set(data) - {"base", "grid"}
        if unknown:
            raise PatrolInputError(f"{source}: unknown top-level key '{sorted(unknown)[0]}' "
                                   f"(a grid batch has 'base' and 'grid')")
        common = data.get("base") or {}
        grid = data["grid"]
        if not isinstance(common, dict) or not isinstance(grid, dict) or not grid:
            raise PatrolInputError(f"{source}: 'base' must be a mapping and 'grid' a non-empty "
                                   f"mapping of key -> list of values")
        keys = list(grid)
        lists = []
        for k in keys:
            v = grid[k]
            if not isinstance(v, list) or not v:
                raise PatrolInputError(f"{source}: grid key '{k}' must be a non-empty list")
            lists.append(v)
        entries = [dict(common, **dict(zip(keys, combo))) for combo in itertools.product(*lists)]
    else:
        raise PatrolInputError(f"{source}: a batch is a list of configurations or a mapping "
                               f"with 'base' and 'grid'")
    out = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise PatrolInputError(f"{source}: entry {i + 1} is not a mapping")
        out.append(base_cfg.updated(entry, f"{source}: entry {i + 1}"))
    if not out:
        raise PatrolInputError(f"{source}: the batch is empty")
    return out
