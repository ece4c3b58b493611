"""Client side of a campaign: the campaign folder (result files, per-run state records,
``runs.csv``). Only the client writes files. Part of :mod:`patrolling_sim.campaign.engine`."""
import collections
import csv
import json
import math
import os
from typing import Dict, List, Optional

import yaml

from patrolling_sim.campaign.spec import (DONE_STATUSES, FAILED_STATUSES, RESULTS_DIR,
                                          STATE_DIR, Campaign, RunSpec)
from patrolling_sim.common.textfile import YamlDumper, YamlLoader


def write_atomic(path, text):
    """Write ``text`` (UTF-8) to ``path`` through ``path.part`` and a rename, so a reader
    never sees half a file; returns the number of bytes written. Plain os.open/os.write:
    the client writes ~9 files per graph run, and this is cheaper than a Python file
    object (bench/notes/campaign.md)."""
    tmp = path + ".part"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
    except FileNotFoundError:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
    try:
        data = text.encode("utf-8")
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
    finally:
        os.close(fd)
    os.replace(tmp, path)
    return len(data)


def load_state(out: str) -> Dict[str, dict]:
    d = os.path.join(out, STATE_DIR)
    state = {}
    if os.path.isdir(d):
        for fn in sorted(os.listdir(d)):
            if fn.endswith(".yaml"):
                with open(os.path.join(d, fn)) as f:
                    rec = yaml.load(f, Loader=YamlLoader) or {}
                if "key" in rec:
                    state[rec["key"]] = rec
    return state


def damaged(out: str, record: dict) -> Optional[str]:
    """Why the files of a stored run in the campaign folder ``out`` no longer match its
    record (a file missing, or of another size than stored), or None when they match. A
    record written before sizes were kept is checked for its info file only."""
    files = record.get("files")
    if files is None and record.get("prefix"):
        files = {record["prefix"] + "_info.csv": None}
    for rel, size in (files or {}).items():
        path = os.path.join(out, rel)
        try:
            actual = os.path.getsize(path)
        except OSError:
            return f"{rel} is missing"
        if size is not None and actual != size:
            return f"{rel} has {actual} bytes, {size} when stored"
    return None


def needs_run(record: Optional[dict], retry_failed: bool) -> bool:
    if record is None:
        return True
    st = record.get("status")
    if st in DONE_STATUSES:
        return False
    if st in FAILED_STATUSES:
        return retry_failed
    return True                                # interrupted, aborted, unknown: redo


def store_result(out: str, spec: RunSpec, result: dict, campaign: Campaign,
                 next_free: Optional[Dict[str, int]] = None) -> dict:
    """Write a finished run's files (as received from the worker, its metrics file included)
    into the campaign tree and its state record (last, so a record always points at complete
    files). Returns the record.

    ``next_free`` (kept by the caller across the runs of one campaign call) remembers, per
    result prefix, the first suffix not yet checked: runs of one second share a time stamp,
    and without it the n-th of them tested the n-1 names taken before it (quadratic in the
    runs per second: a fifth of the client's time in a 1000-run campaign)."""
    files = result.get("files") or {}
    prefix = result.get("prefix")
    dest_prefix = None
    metrics = dict(result.get("metrics") or {}) if prefix else {}
    if prefix:
        base = os.path.join(out, RESULTS_DIR)
        rel = prefix
        # a stamp may repeat across runs (same second): keep every run's files apart
        k = next_free.get(prefix, 0) if next_free is not None else 0
        while any(os.path.exists(os.path.join(base, (rel if k == 0 else f"{prefix}_{k}") + s))
                  for s in ("_info.csv", "_idleness.csv")):
            k += 1
        if k:
            rel = f"{prefix}_{k}"
        if next_free is not None:
            next_free[prefix] = k + 1
        written = {}
        for p, text in files.items():
            target = rel + p[len(prefix):] if p.startswith(prefix) else p
            written[os.path.join(RESULTS_DIR, target)] = write_atomic(
                os.path.join(base, target), text)
        dest_prefix = os.path.join(RESULTS_DIR, rel)
    record = {"key": spec.key, "mode": spec.mode, "config": spec.config,
              "status": result.get("status") or "CRASHED", "rc": result.get("rc"),
              "prefix": dest_prefix, "wall": round(float(result.get("wall") or 0.0), 3),
              "cpu_s": round(float(result.get("cpu_s") or 0.0), 3),
              "code": campaign.code, "provenance": result.get("provenance"),
              "metrics": metrics}
    if prefix:
        record["files"] = written
    if result.get("start_vertices") is not None:
        record["start_vertices"] = [int(v) for v in result["start_vertices"]]
    if result.get("error"):
        record["error"] = result["error"]
    if result.get("warnings"):
        record["warnings"] = result["warnings"]
    if result.get("log_tail") and record["status"] not in DONE_STATUSES:
        record["log_tail"] = result["log_tail"]
    write_atomic(os.path.join(out, STATE_DIR, spec.key + ".yaml"),
                 yaml.dump(record, Dumper=YamlDumper, sort_keys=False))
    return record


def extra_row_columns(spec: RunSpec, record: Optional[dict]) -> dict:
    """Merge hook: further columns of a run's ``runs.csv`` row derived from its configuration
    (the scenario's ``scn_*`` columns are computed with the metrics, in the worker:
    :func:`patrolling_sim.campaign.tasks.run_metrics`). None at present."""
    return {}


#: runs.csv's columns that come after all others, in this order: the start vertex of each
#: robot (space-separated, robot 0 first; empty when the record has none)
LAST_COLUMNS = ("start_vertices",)


def table_rows(campaign: Campaign, state: Dict[str, dict]) -> List[dict]:
    """The rows of ``runs.csv``: one per run of the campaign, in its order (config columns,
    status, metrics, then :data:`LAST_COLUMNS` for the runs that have a record)."""
    rows = []
    for spec in campaign.runs:
        rec = state.get(spec.key)
        row = {"key": spec.key, "mode": spec.mode}
        row.update({k: (json.dumps(v) if isinstance(v, (dict, list)) else v)
                    for k, v in spec.config.items()})
        row["status"] = rec["status"] if rec else "NOT_RUN"
        if rec:
            row["prefix"] = rec.get("prefix")
            row["wall_s"] = rec.get("wall")
            row["cpu_s"] = rec.get("cpu_s")
            row.update(rec.get("metrics") or {})
            row["warnings"] = len(rec.get("warnings") or ())
        row.update(extra_row_columns(spec, rec))
        if rec:
            starts = rec.get("start_vertices")
            row["start_vertices"] = None if starts is None else " ".join(map(str, starts))
        rows.append(row)
    return rows


def write_table(out: str, campaign: Campaign, state: Dict[str, dict]) -> str:
    """``runs.csv``: :func:`table_rows`.

    Written with the csv module as pandas' ``to_csv`` writes a frame of these rows (columns
    in the order they first appear, a missing value or NaN as an empty cell, ``\\n`` line
    ends), so that ``pandas.read_csv`` reads it as before, but without importing pandas: its
    0.2 s of import was on the campaign's critical path, or took CPU from the workers
    (bench/notes/campaign.md). One difference in the text: an integer column with
    empty cells (``rc`` of runs not run) reads ``0``, not pandas' ``0.0``. The columns of
    :data:`LAST_COLUMNS` come last wherever they first appear."""
    rows = table_rows(campaign, state)
    columns = list(dict.fromkeys(k for row in rows for k in row))
    columns = ([c for c in columns if c not in LAST_COLUMNS]
               + [c for c in LAST_COLUMNS if c in columns])
    path = os.path.join(out, "runs.csv")
    tmp = path + ".part"
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(columns)
        w.writerows([_cell(row.get(c)) for c in columns] for row in rows)
    os.replace(tmp, path)
    return path


def _cell(v):
    """A runs.csv cell: None and NaN empty (as pandas writes them), anything else as is."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return v


def _number(text):
    try:
        v = float(text)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(v) else v


#: summary_table's columns: title, runs.csv column whose mean over a group it shows
SUMMARY_MEANS = (("avg_idleness", "idl_avg"), ("max_idleness", "idl_max"),
                 ("visits", "total_visits"), ("time_avg_idleness", "time_avg_idleness"))


def summary_table(out: str) -> str:
    """Text table of runs.csv grouped by map, team size and algorithm: the runs that ended
    with TIMEOUT or CYCLES, their count and the mean of SUMMARY_MEANS (rounded to 2
    decimals, empty cells left out); then the count of each status, and how many runs logged
    warnings. Read with the csv module (pandas' import is 0.2 s of the command)."""
    with open(os.path.join(out, "runs.csv"), newline="") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
    means = [(title, col) for title, col in SUMMARY_MEANS if col in (reader.fieldnames or ())]
    groups = {}
    for row in rows:
        if row.get("status") in DONE_STATUSES[:2]:
            groups.setdefault((row.get("map"), row.get("robots"), row.get("alg")), []).append(row)
    lines = []
    if groups:
        head = ["map", "robots", "alg", "runs"] + [t for t, _ in means]
        table = [head]
        # team sizes in numeric order (a finished run's robots is a validated integer)
        for k in sorted(groups, key=lambda k: (k[0], int(k[1]), k[2])):
            cells = [str(x) for x in k] + [str(len(groups[k]))]
            for _, col in means:
                vals = [v for v in (_number(r.get(col)) for r in groups[k]) if v is not None]
                cells.append(f"{sum(vals) / len(vals):.2f}" if vals else "")
            table.append(cells)
        width = [max(len(r[i]) for r in table) for i in range(len(head))]
        for r in table:                     # text left-aligned, numbers right-aligned
            lines.append("  ".join(c.ljust(w) if i < 3 else c.rjust(w)
                                   for i, (c, w) in enumerate(zip(r, width))).rstrip())
    counts = collections.Counter(row.get("status") for row in rows)
    lines.append("status: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    n = sum(1 for row in rows if (_number(row.get("warnings")) or 0) > 0)
    if n:
        lines.append(f"warnings: {n} run(s) logged warnings (column 'warnings' of runs.csv; "
                     f"the lines are in their state records, {STATE_DIR}/<key>.yaml)")
    return "\n".join(lines)
