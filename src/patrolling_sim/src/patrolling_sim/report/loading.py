"""Find and load experiment results (the original monitor's file formats).

One experiment is one *prefix* ``<dir>/<map>_<N>/<ALG>/<host>/<YYYYMMDD_HHMMSS>[_k]`` with
the files ``<prefix>_info.csv`` (one line, 22 ``;``-separated fields, no header) and
``<prefix>_idleness.csv`` (header ``Time;Robot;Node;Idleness;Interferences``). ROS mode and
graph mode write the same files; graph mode's ``nav_module`` field is ``graph``.

A run is identified by its ``_info.csv`` (written when the run ends). An ``_idleness.csv``
without an ``_info.csv`` belongs to a run that did not finish (killed, crashed, still
running): it is skipped with a one-line warning. A malformed info.csv or idleness.csv is an
error (:class:`PatrolInputError` naming the file and the problem).

Each run's *status* (how it ended, :mod:`patrolling_sim.monitor.run_status`) comes from
``<prefix>_run.yaml``. Older result folders have none: the status is then inferred from
info.csv's termination field, checked against ``<prefix>_config.yaml`` when it exists (a
run that says TIMEOUT but reached less simulated time than its configured timeout was cut
short: it is counted as INTERRUPTED), and the run's ``status_note`` says it was inferred.
Empty idleness fields in info.csv (a run without any idleness sample) load as NaN.
"""
import logging
import math
import os
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from patrolling_sim.common.errors import PatrolInputError
import yaml
from patrolling_sim.model import map_bundle
from patrolling_sim.monitor import run_status as rs
from patrolling_sim.monitor.metrics import compute_metrics
from patrolling_sim.monitor.metrics import read_visits
from patrolling_sim.monitor.run_status import read_run_yaml
from patrolling_sim.monitor.run_status import silences_of
from patrolling_sim.report.result_sets import IDLENESS_SUFFIX, INFO_SUFFIX, find_result_sets

log = logging.getLogger(__name__)

INFO_FIELDS = ("map", "team_size", "initial_positions", "goal_wait", "comm_delay",
               "nav_module", "algorithm", "algorithm_params", "hostname", "date",
               "sim_duration", "real_duration", "interferences", "termination", "idl_min",
               "idl_avg", "idl_stddev", "idl_max", "interference_rate", "total_visits",
               "avg_visits_per_node", "complete_cycles")
_INT_FIELDS = ("team_size", "interferences", "total_visits", "complete_cycles")
_FLOAT_FIELDS = ("goal_wait", "comm_delay", "sim_duration", "real_duration", "idl_min",
                 "idl_avg", "idl_stddev", "idl_max", "interference_rate",
                 "avg_visits_per_node")
IDLENESS_COLUMNS = ("Time", "Robot", "Node", "Idleness", "Interferences")


@dataclass
class Run:
    """One experiment: its info.csv fields and its idleness samples."""
    prefix: str
    info: dict
    samples: pd.DataFrame = field(repr=False)
    status: str = ""
    status_note: str = ""
    #: the visit log (``<prefix>_visits.csv``: time since GO, robot, vertex), kept only for
    #: runs with a scenario (their section draws the graph idleness over time); None
    #: otherwise and for runs written before it existed
    visits: list = field(default=None, repr=False)
    #: (time-averaged graph idleness, worst idleness) from the visit log (docs/metrics.md),
    #: computed once at load; NaN without a log or a readable graph
    extended: tuple = (math.nan, math.nan)
    #: ``_run.yaml``'s ``longest_silence``: per robot id, the longest sim s without a visit
    #: report (docs/monitor.md); [] for runs written before it existed
    silences: list = field(default_factory=list)
    #: the run's ``dead_robot_timeout`` (sim s) from ``_config.yaml`` (runner runs); None if
    #: unknown (graph mode has no dead-robot rule)
    dead_robot_timeout: float = None

    @property
    def label(self):
        """Short unique-ish name: ``ALG N=.. map date``."""
        return (f"{self.info['algorithm']} N={self.info['team_size']} {self.info['map']} "
                f"{os.path.basename(self.prefix)}")

    @property
    def run_id(self):
        """``<map>_<N>/<ALG>/<host>/<date>`` (the prefix relative to its results root)."""
        parts = self.prefix.replace(os.sep, "/").split("/")
        return "/".join(parts[-4:])


def parse_info(path):
    """Parse one ``_info.csv`` file into a dict keyed by :data:`INFO_FIELDS`.

    Raises:
        PatrolInputError: unreadable file, not exactly one non-empty line, not 22 fields,
            or a numeric field that is not a (finite, non-negative) number.
    """
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise PatrolInputError(f"{path}: cannot read info file ({e.__class__.__name__})") from None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise PatrolInputError(f"{path}: empty info file (expected one line of 22 "
                               "';'-separated fields)")
    if len(lines) > 1:
        raise PatrolInputError(f"{path}: {len(lines)} lines, expected one line of 22 fields")
    fields = lines[0].split(";")
    if len(fields) != len(INFO_FIELDS):
        raise PatrolInputError(f"{path}: {len(fields)} ';'-separated fields, expected "
                               f"{len(INFO_FIELDS)}")
    info = dict(zip(INFO_FIELDS, (s.strip() for s in fields)))
    for k in _INT_FIELDS:
        try:
            info[k] = int(info[k])
        except ValueError:
            raise PatrolInputError(f"{path}: field {INFO_FIELDS.index(k) + 1} ({k}) is "
                                   f"'{info[k]}', expected an integer") from None
    for k in _FLOAT_FIELDS:
        if k.startswith("idl_") and info[k] == "":
            info[k] = float("nan")          # no idleness sample in the run
            continue
        try:
            info[k] = float(info[k])
        except ValueError:
            raise PatrolInputError(f"{path}: field {INFO_FIELDS.index(k) + 1} ({k}) is "
                                   f"'{info[k]}', expected a number") from None
        if not math.isfinite(info[k]):
            raise PatrolInputError(f"{path}: field {INFO_FIELDS.index(k) + 1} ({k}) is "
                                   f"'{info[k]}', expected a finite number")
    if info["team_size"] < 1:
        raise PatrolInputError(f"{path}: field 2 (team_size) is {info['team_size']}, expected >= 1")
    for k in ("map", "algorithm"):
        if not info[k]:
            raise PatrolInputError(f"{path}: field {INFO_FIELDS.index(k) + 1} ({k}) is empty")
    return info


def read_idleness(path):
    """Read an ``_idleness.csv`` file into a DataFrame with columns :data:`IDLENESS_COLUMNS`
    (Time, Idleness float; Robot, Node, Interferences int). A header-only file gives an
    empty frame.

    Raises:
        PatrolInputError: missing/unreadable file, wrong header, non-numeric or negative
            values.
    """
    try:
        with open(path, encoding="utf-8") as f:
            header = f.readline().strip()
    except FileNotFoundError:
        raise PatrolInputError(f"{path}: idleness file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise PatrolInputError(
            f"{path}: cannot read idleness file ({e.__class__.__name__})") from None
    if header.split(";") != list(IDLENESS_COLUMNS):
        raise PatrolInputError(f"{path}: header is '{header[:80]}', expected "
                               f"'{';'.join(IDLENESS_COLUMNS)}'")
    fast = _read_idleness_numeric(path)
    if fast is not None:
        return fast
    try:
        df = pd.read_csv(path, sep=";", header=0, dtype=str, skip_blank_lines=True)
    except (pd.errors.ParserError, ValueError) as e:
        raise PatrolInputError(f"{path}: malformed idleness file "
                               f"({str(e).splitlines()[0][:120]})") from None
    out = {}
    for col in IDLENESS_COLUMNS:
        vals = pd.to_numeric(df[col], errors="coerce")
        bad = vals.isna() | ~np.isfinite(vals.astype(float))
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise PatrolInputError(f"{path}:{i + 2}: column {col} is '{df[col].iloc[i]}', "
                                   f"expected a number")
        out[col] = vals.astype(float)
    frame = pd.DataFrame(out)
    for col in ("Robot", "Node", "Interferences"):
        frac = frame[col] != frame[col].round()
        if frac.any():
            i = int(np.flatnonzero(frac.to_numpy())[0])
            raise PatrolInputError(f"{path}:{i + 2}: column {col} is '{df[col].iloc[i]}', "
                                   f"expected an integer")
        frame[col] = frame[col].astype(np.int64)
    for col in ("Node", "Idleness"):
        neg = frame[col] < 0
        if neg.any():
            i = int(np.flatnonzero(neg.to_numpy())[0])
            raise PatrolInputError(
                f"{path}:{i + 2}: column {col} is negative ('{df[col].iloc[i]}')")
    return frame


def _read_idleness_numeric(path):
    """The idleness frame of a well-formed file, parsed as numbers at once (4.7 against
    12.5 ms for a 4-robot hour on cumberland, bench/notes/campaign.md); None if anything
    is off, and the checked path then finds and names the bad line."""
    try:
        df = pd.read_csv(path, sep=";", header=0, skip_blank_lines=True,
                         dtype={"Time": float, "Robot": float, "Node": float,
                                "Idleness": float, "Interferences": float})
    except (pd.errors.ParserError, ValueError, TypeError):
        return None
    if list(df.columns) != list(IDLENESS_COLUMNS):
        return None
    vals = df.to_numpy(dtype=float)
    if vals.size and not np.isfinite(vals).all():
        return None
    ints = vals[:, [1, 2, 4]]
    if (ints != np.round(ints)).any() or (vals[:, [2, 3]] < 0).any():
        return None
    frame = pd.DataFrame({c: df[c].astype(float) for c in IDLENESS_COLUMNS})
    for col in ("Robot", "Node", "Interferences"):
        frame[col] = frame[col].astype(np.int64)
    return frame


def _config_number(prefix, key):
    """The number ``key`` of ``<prefix>_config.yaml`` (written by the runner), or None if
    there is no such file or value."""
    try:
        with open(prefix + "_config.yaml", encoding="utf-8") as f:
            return float((yaml.safe_load(f) or {})[key])
    except (OSError, KeyError, TypeError, ValueError, AttributeError, yaml.YAMLError):
        return None


def run_status_of(prefix, info, rec=False):
    """(status, note) of a run: from ``<prefix>_run.yaml`` (``rec``: its record when already
    read, None if it has none), else inferred (see the module docstring)."""
    if rec is False:
        rec = rs.read_run_yaml(prefix)
    if rec and rec.get("status"):
        status = rs.normalise(rec["status"])
        note = str(rec.get("reason") or "")
        if rec.get("written_by") == "monitor" and rec.get("exit_code") is None and \
                status == rs.INTERRUPTED:
            note += " (the runner did not record the end: it was killed)"
        return status, note
    status = rs.normalise(info["termination"])
    note = "no _run.yaml (older run): status from info.csv"
    if status == rs.TIMEOUT:
        try:
            with open(prefix + "_config.yaml", encoding="utf-8") as f:
                timeout = float((yaml.safe_load(f) or {}).get("timeout") or 0)
        except (OSError, ValueError, TypeError, AttributeError):
            timeout = None
        except Exception:   # noqa: BLE001 - a malformed config only loses the check
            timeout = None
        if timeout and info["sim_duration"] < timeout - 1.0:
            return rs.INTERRUPTED, (f"no _run.yaml (older run): info.csv says TIMEOUT but only "
                                    f"{info['sim_duration']:.1f} of {timeout:g} sim s ran "
                                    f"(config.yaml): counted as cut short")
        note += " (not verified)" if timeout is None else " (checked against config.yaml)"
    return status, note


#: the idleness columns a report keeps without per-run time plots (``load_run(slim=True)``)
SLIM_COLUMNS = ("Node", "Idleness")


def load_run(prefix, slim=False):
    """Load one run (info + idleness samples + status + the visit log's extended metrics).
    ``slim``: keep only :data:`SLIM_COLUMNS` of the samples, Node as int32 (what the tables,
    box plots, histograms and heat maps use; the time plots need the rest).

    The extended metrics come from ``<prefix>_metrics.yaml`` when a campaign wrote one
    (computed from the same visit log, where the run ran), else from the visit log; the log
    itself is kept only for runs with a ``_scenario.yaml``: a campaign's report loads
    thousands of runs, and their logs were most of its memory."""
    info = parse_info(prefix + INFO_SUFFIX)
    samples = read_idleness(prefix + IDLENESS_SUFFIX)
    if slim:
        samples = pd.DataFrame({"Node": samples["Node"].astype(np.int32),
                                "Idleness": samples["Idleness"]})
    rec = read_run_yaml(prefix)
    status, note = run_status_of(prefix, info, rec)
    run = Run(prefix=prefix, info=info, samples=samples, status=status, status_note=note)
    run.silences = silences_of(rec)
    run.dead_robot_timeout = _config_number(prefix, "dead_robot_timeout")
    run.extended = _stored_extended(prefix)
    scenario = os.path.isfile(prefix + "_scenario.yaml")
    if run.extended is None or scenario:
        visits = None
        if os.path.isfile(prefix + "_visits.csv"):
            try:
                visits = read_visits(prefix + "_visits.csv")
            except ValueError as e:
                log.warning("%s (no extended metrics for this run)", e)
        if run.extended is None:
            run.extended = _extended_from_visits(visits, info)
        if scenario:
            run.visits = visits
    return run


def _stored_extended(prefix):
    """(time_avg_idleness, worst_idleness) of ``<prefix>_metrics.yaml``, None without a
    readable file holding both."""
    path = prefix + "_metrics.yaml"
    if not os.path.isfile(path):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            doc = yaml.load(f, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
        return (float(doc["time_avg_idleness"]), float(doc["worst_idleness"]))
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError):
        return None


def _extended_from_visits(visits, info):
    """(time-averaged graph idleness, worst idleness) of a visit log (docs/metrics.md);
    NaN without a log, a duration or a readable graph of the map."""
    if visits is None or not info["sim_duration"]:
        return (math.nan, math.nan)
    try:
        n = map_bundle.vertex_count(info["map"])
    except Exception:                          # noqa: BLE001 - unreadable map: no metric
        return (math.nan, math.nan)
    m = compute_metrics(visits, n, float(info["sim_duration"]))
    return (m.time_avg_idleness, m.worst_idleness)


def load_runs(dirs, slim=False):
    """Find and load every run under ``dirs`` (``slim``: see :func:`load_run`). Returns
    (runs, warnings, unreadable): ``unreadable`` lists ``(prefix, why)`` for every result set
    that could not be used: a malformed or partial file (the error's line), or a
    ``_run.yaml`` without an info file (the status it records). A report excludes them and
    says so; it never refuses the other runs because of them."""
    found = find_result_sets(dirs)
    runs, unreadable = [], []
    for p in found.prefixes:
        try:
            runs.append(load_run(p, slim))
        except PatrolInputError as e:
            unreadable.append((p, f"unreadable result files: {e}"))
    for p in found.unfinished:
        rec = read_run_yaml(p) or {}
        unreadable.append((p, f"no {INFO_SUFFIX} (the monitor wrote none); _run.yaml "
                              f"records status {rec.get('status') or '?'}"
                              + (f": {rec['reason']}" if rec.get("reason") else "")))
    return runs, found.warnings, sorted(unreadable)
