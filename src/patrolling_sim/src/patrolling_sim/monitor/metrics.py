"""Patrolling metrics beyond the original monitor's, computed from a run's visit log.

The original monitor (:mod:`patrolling_sim.monitor.core`) averages *idleness samples*: one
sample per visit, the time since the previous visit of that vertex. The literature also uses
the *instantaneous* idleness of the graph over time (Machado et al. 2002, "Multi-agent
patrolling: an empirical analysis of alternative architectures"), which weights a long gap by
how long it lasted, and counts the time before a vertex's first visit and after its last one.
This module computes those from the visit log, in both modes, with one function. Every
definition is in ``docs/metrics.md``.

Input: the visit reports after GO as ``(t, robot, vertex)`` with ``t`` in seconds since GO
(what the monitor receives as ``[id,11,v]``, the start-vertex reports included), the vertex
count and the run's duration. The instantaneous idleness of a vertex is 0 at GO, grows at
rate 1, and drops to 0 at each visit.

Pure: no ROS, no files (:func:`read_visits` / :func:`write_metrics` are the file helpers).
"""
import csv
import math
from collections import OrderedDict
from dataclasses import asdict, dataclass, field
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from patrolling_sim.monitor.results import VISITS_HEADER

#: percentiles of the idleness samples reported by :func:`compute_metrics`
PERCENTILES = (50, 90, 95, 99)


@dataclass
class RunMetrics:
    """Metrics of one run (times in s, rates per hour). See ``docs/metrics.md``."""
    duration: float
    n_vertices: int
    n_visits: int
    # the original's definition: mean of the idleness samples (one per visit after the first)
    sample_avg_idleness: Optional[float]
    sample_max_idleness: Optional[float]
    # instantaneous idleness averaged over vertices and time (Machado et al. 2002)
    time_avg_idleness: float
    # highest instantaneous idleness of any vertex at any time, open gaps included
    worst_idleness: float
    # time average of the instantaneous maximum over vertices
    time_avg_max_idleness: float
    idleness_percentiles: Dict[str, Optional[float]]
    visit_frequency_mean: float        # visits per hour per vertex
    visit_frequency_sd: float          # population SD over vertices
    never_visited: int
    # share of the vertex-time V x T inside the idleness samples (closed gaps): what share of
    # the run sample_avg_idleness describes; the rest is open gaps (before a vertex's first
    # visit, after its last, vertices never visited), which the samples leave out
    sample_coverage: float
    per_vertex_visits: List[int] = field(default_factory=list)
    extra: Dict[str, object] = field(default_factory=dict)

    def to_dict(self):
        return asdict(self)


def _vertex_gaps(times: Sequence[float], duration: float) -> List[float]:
    """Lengths of the intervals of a vertex's idleness: GO -> first visit, visit -> visit, last
    visit -> end (visits after ``duration`` ignored)."""
    gaps, prev = [], 0.0
    for t in times:
        if t > duration:
            break
        gaps.append(max(0.0, t - prev))
        prev = t
    gaps.append(max(0.0, duration - prev))
    return gaps


def _time_avg_max(visit_times: List[List[float]], duration: float) -> float:
    """(1/T) * integral over [0, T] of max_v idleness_v(t). Between two consecutive events the
    maximum is the idleness of the vertex with the oldest last visit, so it grows at rate 1 from
    ``t - oldest``; the events are all visits, in time order."""
    if duration <= 0:
        return 0.0
    events = sorted((t, v) for v, ts in enumerate(visit_times) for t in ts if t <= duration)
    # the vertices in the order of their last visit (events come in time order, so the first
    # is the oldest): the minimum in O(1) per event instead of a scan of every vertex
    last = OrderedDict((v, 0.0) for v in range(len(visit_times)))
    area, t_prev = 0.0, 0.0
    for t, v in events + [(duration, None)]:
        oldest = last[next(iter(last))] if last else 0.0
        # idleness of the oldest vertex grows from t_prev - oldest to t - oldest
        a, b = t_prev - oldest, t - oldest
        area += (a + b) / 2.0 * (t - t_prev)
        if v is not None:
            last[v] = t
            last.move_to_end(v)
        t_prev = t
    return area / duration


def compute_metrics(visits: Iterable[Tuple[float, int, int]], n_vertices: int,
                    duration: float, extra: Optional[Dict[str, object]] = None) -> RunMetrics:
    """Metrics of a run from its visit log.

    Args:
        visits: ``(t, robot, vertex)`` reports, ``t`` = seconds since GO; any order.
        n_vertices: V (vertices never reported count as unvisited for the whole run).
        duration: seconds from GO to the end of the run (> 0).
        extra: driver-measured figures copied into the result (distance per robot, waiting
            share, messages...), see ``docs/metrics.md``.

    Raises:
        ValueError: ``n_vertices`` < 1, ``duration`` < 0, or a vertex id outside the graph.
    """
    if n_vertices < 1:
        raise ValueError(f"n_vertices must be >= 1, got {n_vertices}")
    if duration < 0:
        raise ValueError(f"duration must be >= 0, got {duration}")
    times: List[List[float]] = [[] for _ in range(n_vertices)]
    n = 0
    for t, _robot, v in visits:
        if not 0 <= int(v) < n_vertices:
            raise ValueError(f"visit of vertex {v} outside a graph of {n_vertices} vertices")
        if float(t) <= duration:
            times[int(v)].append(float(t))
            n += 1
    for ts in times:
        ts.sort()
    samples = [b - a for ts in times for a, b in zip(ts, ts[1:])]
    area, worst = 0.0, 0.0
    for ts in times:
        gaps = _vertex_gaps(ts, duration)
        area += sum(g * g / 2.0 for g in gaps)
        worst = max(worst, max(gaps))
    hours = duration / 3600.0
    counts = [len(ts) for ts in times]
    freq = np.array(counts, dtype=float) / hours if hours > 0 else np.zeros(n_vertices)
    pct = {f"p{p}": (float(np.percentile(samples, p)) if samples else None) for p in PERCENTILES}
    return RunMetrics(
        duration=float(duration),
        n_vertices=n_vertices,
        n_visits=n,
        sample_avg_idleness=float(np.mean(samples)) if samples else None,
        sample_max_idleness=float(max(samples)) if samples else None,
        time_avg_idleness=area / (n_vertices * duration) if duration > 0 else 0.0,
        worst_idleness=worst,
        time_avg_max_idleness=_time_avg_max(times, duration),
        idleness_percentiles=pct,
        visit_frequency_mean=float(freq.mean()),
        visit_frequency_sd=float(freq.std()),
        never_visited=sum(1 for c in counts if c == 0),
        sample_coverage=sum(samples) / (n_vertices * duration) if duration > 0 else 0.0,
        per_vertex_visits=counts,
        extra=dict(extra or {}),
    )


def read_visits(path: str) -> List[Tuple[float, int, int]]:
    """Read a ``<prefix>_visits.csv`` (``Time;Robot;Node``, time since GO).

    Raises:
        ValueError: a malformed file (one line naming the file and the line).
    """
    out = []
    with open(path, newline="") as f:
        rows = csv.reader(f, delimiter=";")
        header = next(rows, None)
        if header is None or ";".join(h.strip() for h in header) != VISITS_HEADER:
            raise ValueError(f"{path}: expected the header '{VISITS_HEADER}'")
        for k, row in enumerate(rows, start=2):
            if not row:
                continue
            try:
                out.append((float(row[0]), int(row[1]), int(row[2])))
            except (IndexError, ValueError):
                raise ValueError(f"{path}:{k}: expected time;robot;vertex, got {';'.join(row)!r}")
    return out


def metrics_to_yaml_dict(m: RunMetrics) -> dict:
    """Plain types only (for yaml.safe_dump): numpy scalars and NaN removed."""
    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, (np.floating, float)):
            x = float(x)
            return None if math.isnan(x) else round(x, 6)
        if isinstance(x, np.integer):
            return int(x)
        return x
    return clean(m.to_dict())


# ----------------------------------------------------------------------------- over time
def graph_idleness_series(visits: Iterable[Tuple[float, int, int]], n_vertices: int,
                          duration: float, step: float = 1.0):
    """(times, mean over vertices of the instantaneous idleness at those times), sampled every
    ``step`` s from 0 to ``duration``: the curve the report draws, and the input of
    :func:`failure_impact`."""
    times = np.arange(0.0, duration + 1e-9, step)
    per_v: List[List[float]] = [[] for _ in range(n_vertices)]
    for t, _r, v in visits:
        per_v[int(v)].append(float(t))
    total = np.zeros_like(times)
    for ts in per_v:
        ts = np.sort(np.asarray(ts))
        k = np.searchsorted(ts, times, side="right")         # visits at or before each time
        last = np.where(k > 0, ts[np.maximum(k - 1, 0)] if len(ts) else 0.0, 0.0)
        total += times - last
    return times, total / n_vertices


@dataclass
class FailureImpact:
    """Graph idleness around one failure (s); see ``docs/metrics.md``."""
    t_fail: float
    before: float                  # time average over the window before the failure
    after: float                   # time average over the settled part after it
    settle_time: Optional[float]   # s after the failure until the smoothed curve stays within
    #                                the band around `after`; None if it never does


def failure_impact(times, series, t_fail: float, t_end: float, window: float = 600.0,
                   smooth: float = 300.0, band: float = 0.1) -> FailureImpact:
    """Impact of a failure at ``t_fail`` on the graph idleness ``series`` (from
    :func:`graph_idleness_series`), up to ``t_end`` (the next failure or the end of the run).

    ``before``: mean of the series over [t_fail - window, t_fail). ``after``: mean over the
    last ``min(window, (t_end - t_fail) / 2)`` s before ``t_end`` (the settled level).
    ``settle_time``: the first delay after the failure from which the *trailing* average of
    the series over ``smooth`` s (causal: it only looks back, so the end of the run is not
    distorted) stays within ``band`` (relative) of ``after`` until ``t_end``; None if it
    never does."""
    times = np.asarray(times, dtype=float)
    series = np.asarray(series, dtype=float)
    pre = (times >= max(0.0, t_fail - window)) & (times < t_fail)
    tail = min(window, (t_end - t_fail) / 2.0)
    post = (times >= t_end - tail) & (times <= t_end)
    before = float(series[pre].mean()) if pre.any() else float("nan")
    after = float(series[post].mean()) if post.any() else float("nan")
    settle = None
    sel = np.nonzero((times >= t_fail) & (times <= t_end))[0]
    if len(sel) and math.isfinite(after) and after > 0:
        step = float(times[1] - times[0]) if len(times) > 1 else 1.0
        w = max(1, int(round(smooth / step)))
        c = np.concatenate(([0.0], np.cumsum(series)))
        idx = np.arange(len(series))
        lo = np.maximum(0, idx - w + 1)
        trailing = (c[idx + 1] - c[lo]) / (idx + 1 - lo)
        outside = np.abs(trailing[sel] - after) > band * after
        if not outside.any():
            settle = 0.0
        elif not outside[-1]:
            last_out = int(np.nonzero(outside)[0][-1])
            settle = float(times[sel[last_out + 1]] - t_fail)
    return FailureImpact(float(t_fail), before, after, settle)
