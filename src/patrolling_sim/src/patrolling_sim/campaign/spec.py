"""Campaign files: reading and validating a campaign (YAML grid), the run specs and their
stable keys. Part of :mod:`patrolling_sim.campaign.engine` (see its docstring and
docs/campaigns.md)."""
import dataclasses
import hashlib
import itertools
import json
import os
import subprocess
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import yaml

from patrolling_sim.campaign.run_warnings import RunWarnings
from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.algorithms import REGISTRY, names
from patrolling_sim.experiment.validation import strategy_params
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.runner.config import ExperimentConfig

MODES = ("graph", "ros")
#: statuses of a run that ended normally: skipped when the campaign is run again
DONE_STATUSES = ("TIMEOUT", "CYCLES", "FAIL")
#: statuses redone only with ``retry_failed``
FAILED_STATUSES = ("CRASHED", "ERROR")
TOP_KEYS = ("name", "mode", "fixed", "grid", "seeds")
#: configuration keys a campaign may not set (the campaign decides them)
RESERVED = {"graph": ("results_dir",),
            "ros": ("results_dir", "rviz", "gui_sim", "record", "record_period")}
STATE_DIR = "state"
RESULTS_DIR = "results"


@dataclass
class RunSpec:
    key: str
    mode: str
    config: Dict[str, object]

    def label(self):
        c = self.config
        return f"{c.get('map')}_{c.get('robots')} {c.get('alg')} seed {c.get('seed')}"


@dataclass
class Campaign:
    name: str
    mode: str
    path: str
    runs: List[RunSpec]
    raw: dict
    code: Dict[str, object]
    #: the warnings validating the runs gave, each once: "<message> (in N of the M runs)"
    warnings: List[str] = field(default_factory=list)


# ----------------------------------------------------------------------------- configuration
def _config_class(mode):
    if mode == "graph":
        return GraphSimConfig
    return ExperimentConfig


def config_fields(mode) -> Dict[str, dataclasses.Field]:
    """Configuration keys of ``mode`` a campaign may set -> dataclass field."""
    return {f.name: f for f in dataclasses.fields(_config_class(mode))
            if f.name not in RESERVED[mode]}


def _default(f):
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def _check_type(where, key, value, f):
    """One-line error unless ``value`` fits field ``f`` (by its default's type)."""
    proto = _default(f)
    ok = True
    if key in ("map", "alg", "initpos") or isinstance(proto, str):
        ok = isinstance(value, str) or (key == "initpos" and isinstance(value, int))
        want = "a string"
    elif isinstance(proto, bool):
        ok, want = isinstance(value, bool), "true or false"
    elif isinstance(proto, int) or key in ("robots", "seed", "cycles"):
        ok, want = isinstance(value, int) and not isinstance(value, bool), "an integer"
    elif isinstance(proto, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        want = "a number"
    elif isinstance(proto, dict):
        ok, want = isinstance(value, dict), "a mapping"
    if not ok:
        raise PatrolInputError(f"{where}.{key}: expected {want}, got {value!r}")


def code_version(root: Optional[str] = None) -> Dict[str, object]:
    """``{"commit": sha or "unknown", "dirty": bool or None}`` of the workspace."""
    root = root or paths.source_root()
    if root is None:                  # an install space: no git checkout to ask
        return {"commit": "unknown", "dirty": None}
    try:
        commit = subprocess.run(["git", "-C", root, "rev-parse", "HEAD"], capture_output=True,
                                text=True, timeout=10, check=True).stdout.strip()
        status = subprocess.run(["git", "-C", root, "status", "--porcelain", "--", "src",
                                 "scripts", "maps", "params", "MSP"], capture_output=True,
                                text=True, timeout=10, check=True).stdout
        return {"commit": commit, "dirty": bool(status.strip())}
    except (OSError, subprocess.SubprocessError):
        return {"commit": "unknown", "dirty": None}


def run_key(mode: str, config: dict, commit: str) -> str:
    """The run's stable key: a hash of ``mode``, ``config`` (the files its algorithm reads
    named by their content, :func:`keyed_config`) and ``commit``."""
    blob = json.dumps({"mode": mode, "config": keyed_config(config), "code": commit},
                      sort_keys=True, default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:16]


def keyed_config(config: dict) -> dict:
    """``config`` as run keys see it: the files its algorithm reads
    (:meth:`~patrolling_sim.algorithms.base.PatrolStrategy.content_params`, e.g. POLICY's
    policy file) replaced by their content's identity, at the top level when ``config`` has
    the key (``policy``) and in ``params`` when they name it there. Other algorithms'
    configurations are returned as they are (their keys do not change)."""
    cls = REGISTRY.get(config.get("alg"))
    if cls is None:
        return config
    ids = cls.content_params(strategy_params(config.get("params"), config.get("policy")))
    if not ids:
        return config
    out = dict(config)
    for k, v in ids.items():
        if k in out:
            out[k] = v
        params = out.get("params") or {}
        if k in params or k not in out:
            out["params"] = dict(params, **{k: v})
    return out


def _read_file(path):
    """The top-level mapping of the campaign file ``path``, its keys checked against
    TOP_KEYS. Raises PatrolInputError: the file cannot be read, is not valid YAML (with its
    line when known), is not a mapping or has an unknown key."""
    try:
        with open(path) as f:
            raw = yaml.safe_load(f)
    except OSError as e:
        raise PatrolInputError(f"{path}: cannot read the campaign file ({e.strerror})")
    except yaml.YAMLError as e:
        line = getattr(getattr(e, "problem_mark", None), "line", None)
        raise PatrolInputError(f"{path}: not valid YAML" +
                               (f" (line {line + 1})" if line is not None else ""))
    if not isinstance(raw, dict):
        raise PatrolInputError(f"{path}: expected a mapping with the keys {', '.join(TOP_KEYS)}")
    for k in raw:
        if k not in TOP_KEYS:
            raise PatrolInputError(f"{path}: unknown key '{k}' (known: {', '.join(TOP_KEYS)})")
    return raw


def _sections(path, raw, mode, fields):
    """(fixed, grid) of the campaign file's mapping ``raw``: its ``fixed`` settings and its
    ``grid`` (a new dict) with ``seeds`` turned into ``grid.seed`` and ``"all"`` maps or
    algorithms expanded. Raises PatrolInputError: a section is not a mapping, names a key
    not in ``fields`` (of ``mode``), or ``seeds`` is bad or given with ``grid.seed``."""
    fixed = raw.get("fixed") or {}
    grid = raw.get("grid") or {}
    for where, d in (("fixed", fixed), ("grid", grid)):
        if not isinstance(d, dict):
            raise PatrolInputError(f"{path}: {where}: expected a mapping of configuration keys")
        for k in d:
            if k not in fields:
                raise PatrolInputError(f"{path}: {where}.{k}: unknown configuration key for mode "
                                       f"{mode} (known: {', '.join(sorted(fields))})")
    if "seeds" in raw:
        n = raw["seeds"]
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise PatrolInputError(f"{path}: seeds: expected an integer >= 1, got {n!r}")
        if "seed" in grid:
            raise PatrolInputError(f"{path}: seeds: give either seeds or grid.seed, not both")
        grid = dict(grid, seed=list(range(n)))
    grid = dict(grid)
    for k in ("map", "alg"):                   # "all": every shipped map / registered algorithm
        if grid.get(k) == "all":
            if k == "map":
                grid[k] = paths.available_maps()
            else:
                grid[k] = names()
    return fixed, grid


def _check_values(path, fixed, grid, fields):
    """Check the values of ``fixed`` and ``grid`` against ``fields``: each grid value a
    non-empty list of values of the field's type, no key in both, every map named found
    with its graph file. Raises PatrolInputError naming the first key that is wrong."""
    for k, values in grid.items():
        if not isinstance(values, list):
            raise PatrolInputError(f"{path}: grid.{k}: expected a list of values")
        if not values:
            raise PatrolInputError(f"{path}: grid.{k}: empty list (no run would be made)")
        for v in values:
            _check_type(f"{path}: grid", k, v, fields[k])
    for k, v in fixed.items():
        _check_type(f"{path}: fixed", k, v, fields[k])
    for k in set(fixed) & set(grid):
        raise PatrolInputError(f"{path}: {k}: set both in fixed and in grid")
    for where, values in (("fixed", [fixed["map"]] if "map" in fixed else []),
                          ("grid", grid.get("map", []))):
        for m in values:
            try:
                yaml_path, graph_path = paths.map_files(m)
            except PatrolInputError as e:
                raise PatrolInputError(f"{path}: {where}.map: {e}")
            if not os.path.isfile(graph_path):
                raise PatrolInputError(f"{path}: {where}.map: no graph file {graph_path}")


def _make_runs(path, mode, fields, fixed, grid, commit):
    """(runs, warning counts): one validated RunSpec per combination of the ``grid`` values
    (in the grid's key order), its configuration the fields' defaults, then ``fixed``, then
    the combination, keyed with ``commit``; and {message: number of runs} of the warnings
    the validation logged (counted, not printed once per run: a campaign of a thousand runs
    would print each a thousand times). Raises PatrolInputError naming the run whose
    configuration is invalid."""
    cls = _config_class(mode)
    keys = list(grid)
    runs = []
    with RunWarnings() as warned:
        for combo in itertools.product(*(grid[k] for k in keys)):
            cfg = {n: _default(f) for n, f in fields.items()}
            cfg.update(fixed)
            cfg.update(zip(keys, combo))
            where = ", ".join(f"{k}={v}" for k, v in zip(keys, combo)) or "the fixed settings"
            try:
                obj = cls(**cfg)
                obj.validate()
            except (PatrolInputError, TypeError, ValueError) as e:
                raise PatrolInputError(f"{path}: run with {where}: {e}")
            runs.append(RunSpec(run_key(mode, cfg, commit), mode, cfg))
    return runs, warned.counts


def load_campaign(path: str, code: Optional[Dict[str, object]] = None) -> Campaign:
    """Read and validate a campaign file; every run is validated. ``code``: the code
    version the run keys use (default: :func:`code_version` of the workspace).

    Raises:
        PatrolInputError: one line naming the file and the key that is wrong.
    """
    raw = _read_file(path)
    mode = raw.get("mode", "graph")
    if mode not in MODES:
        raise PatrolInputError(f"{path}: mode: expected one of {', '.join(MODES)}, got {mode!r}")
    fields = config_fields(mode)
    fixed, grid = _sections(path, raw, mode, fields)
    _check_values(path, fixed, grid, fields)
    code = code or code_version()
    runs, counts = _make_runs(path, mode, fields, fixed, grid, str(code["commit"]))
    if not runs:
        raise PatrolInputError(f"{path}: no run (give grid values or fixed settings)")
    if len({r.key for r in runs}) != len(runs):
        raise PatrolInputError(f"{path}: the grid repeats a run (same configuration twice)")
    name = raw.get("name") or os.path.splitext(os.path.basename(path))[0]
    n = len(runs)
    warnings = [msg + (f" (in {k} of the {n} runs)" if n > 1 else "")
                for msg, k in counts.items()]
    if not grid:
        unset = sorted(set(fields) - set(fixed) - set(RESERVED.get(mode, ())))
        warnings.insert(0, f"{path}: grid and seeds vary nothing: the campaign is one run of "
                        f"the fixed settings, every other key at its default "
                        f"({', '.join(unset[:6])}{', ...' if len(unset) > 6 else ''})")
    return Campaign(str(name), mode, os.path.abspath(path), runs, raw, code,
                    warnings=warnings)
