"""Per-run metrics and the summary table (mean and sample SD over runs).

Per run:

- ``avg_idleness``  mean of the run's idleness.csv samples (the monitor's global average);
- ``max_idleness``  max of those samples;
- ``time_avg_idleness``, ``worst_idleness`` from the run's visit log (``<prefix>_visits.csv``,
  docs/metrics.md; NaN for runs without one);
- ``complete_cycles``, ``interference_rate`` from info.csv;
- ``info_idl_avg`` info.csv's value, and ``idl_avg_agrees``: whether it matches the samples'
  mean within the 0.1 s print resolution (0.05 rounding of the file plus 0.05 rounding of
  each sample). The original writes info.csv's idleness fields at the last completed cycle,
  so a disagreement is reported, not fatal; the table always uses the samples.

An algorithm whose runs differ by their ``algorithm_params`` (``params_in_label``: POLICY,
whose params are the policy file's label) is named ``NAME params``.

Runs are grouped by map, team size, algorithm and by every experimental setting that varies
among the loaded runs (navigation module, initial positions, goal wait, communication
delay), so runs made under different settings are never averaged together.
"""
import numpy as np
import pandas as pd

from patrolling_sim.algorithms.base import display_name
from patrolling_sim.monitor.run_status import longest_silence

KEY = ("map", "N", "algorithm")
#: settings that split groups when they differ between loaded runs
SETTINGS = ("nav_module", "initial_positions", "goal_wait", "comm_delay")
METRICS = ("avg_idleness", "max_idleness", "time_avg_idleness", "worst_idleness",
           "complete_cycles", "interference_rate")
METRIC_LABELS = {
    "avg_idleness": "Avg idleness (s)",
    "max_idleness": "Max idleness (s)",
    "time_avg_idleness": "Time-avg graph idleness (s)",
    "worst_idleness": "Worst idleness (s)",
    "complete_cycles": "Complete cycles",
    "interference_rate": "Interference rate (1/min)",
}
AGREE_TOL = 0.1


def extended_metrics(run):
    """(time-averaged graph idleness, worst idleness) of a run (docs/metrics.md), computed
    when it was loaded (:func:`patrolling_sim.report.loading.load_run`); NaN without a
    visit log or a readable graph."""
    return run.extended


def run_table(runs):
    """DataFrame with one row per run (columns: run_id, prefix, KEY, SETTINGS, metrics,
    samples, info_idl_avg, idl_avg_agrees, sim_duration, termination, ...)."""
    rows = []
    for r in runs:
        idl = r.samples["Idleness"].to_numpy(dtype=float)
        i = r.info
        avg = float(idl.mean()) if idl.size else np.nan
        t_avg, worst = extended_metrics(r)
        silent_s, silent_robot = longest_silence(r.silences)
        rows.append({
            "run_id": r.run_id,
            "prefix": r.prefix,
            "map": i["map"],
            "N": i["team_size"],
            # "POLICY <file>@<hash>": runs of different policy files are never averaged
            "algorithm": display_name(i["algorithm"], i["algorithm_params"]),
            "nav_module": i["nav_module"],
            "initial_positions": i["initial_positions"],
            "goal_wait": i["goal_wait"],
            "comm_delay": i["comm_delay"],
            "algorithm_params": i["algorithm_params"],
            "hostname": i["hostname"],
            "date": i["date"],
            "samples": int(idl.size),
            "avg_idleness": avg,
            "max_idleness": float(idl.max()) if idl.size else np.nan,
            "time_avg_idleness": t_avg,
            "worst_idleness": worst,
            "complete_cycles": i["complete_cycles"],
            "interference_rate": i["interference_rate"],
            "interferences": i["interferences"],
            "total_visits": i["total_visits"],
            "sim_duration": i["sim_duration"],
            "real_duration": i["real_duration"],
            "termination": i["termination"],
            "status": r.status or i["termination"],
            "status_note": r.status_note,
            # the longest sim s any robot went without a visit report, and which robot
            "longest_silence": np.nan if silent_s is None else silent_s,
            "longest_silence_robot": -1 if silent_robot is None else silent_robot,
            "info_idl_avg": i["idl_avg"],
            "idl_avg_agrees": bool(idl.size and abs(avg - i["idl_avg"]) <= AGREE_TOL)
            if not np.isnan(i["idl_avg"]) else not idl.size,
        })
    df = pd.DataFrame(rows)
    if not df.empty:
        df = df.sort_values(list(KEY) + ["date", "run_id"], kind="stable").reset_index(drop=True)
    return df


def varying_settings(per_run):
    """The SETTINGS columns whose values differ between runs."""
    return [s for s in SETTINGS if per_run[s].nunique(dropna=False) > 1]


def group_columns(per_run):
    """Grouping columns: map, N, the varying settings, algorithm."""
    return ["map", "N"] + varying_settings(per_run) + ["algorithm"]


def status_counts(per_run_all, cols):
    """{group key tuple: 'TIMEOUT 3, CRASHED 1'} over every loaded run (used or not)."""
    out = {}
    for key, g in per_run_all.groupby(cols, sort=True, dropna=False):
        key = key if isinstance(key, tuple) else (key,)
        counts = g["status"].value_counts()
        out[key] = ", ".join(f"{s} {int(n)}" for s, n in sorted(counts.items()))
    return out


def summary_table(per_run, per_run_all=None):
    """One row per group: group columns, ``runs``, ``samples``, ``statuses`` (the status
    counts of every loaded run of the group, ``per_run_all``, including runs left out of the
    means) and ``<metric>_mean`` / ``<metric>_sd`` for each metric (sd = sample SD over runs,
    NaN for a single run). Runs without idleness samples count in ``runs`` but not in the
    idleness means."""
    cols = group_columns(per_run)
    counts = status_counts(per_run if per_run_all is None else per_run_all, cols) \
        if "status" in per_run else {}
    out = []
    for key, g in per_run.groupby(cols, sort=True, dropna=False):
        key = key if isinstance(key, tuple) else (key,)
        row = dict(zip(cols, key))
        row["runs"] = int(len(g))
        row["statuses"] = counts.get(key, "")
        row["samples"] = int(g["samples"].sum())
        for m in METRICS:
            v = g[m].dropna().to_numpy(dtype=float)
            row[f"{m}_mean"] = float(v.mean()) if v.size else np.nan
            row[f"{m}_sd"] = float(v.std(ddof=1)) if v.size > 1 else np.nan
        out.append(row)
    return pd.DataFrame(out, columns=cols + ["runs", "statuses", "samples"] +
                        [f"{m}_{s}" for m in METRICS for s in ("mean", "sd")])


def fmt_mean_sd(mean, sd, digits=1):
    """'12.3 ± 4.5', '12.3 ± n/a' (single run) or 'n/a'."""
    if mean is None or (isinstance(mean, float) and np.isnan(mean)):
        return "n/a"
    sd_s = "n/a" if sd is None or np.isnan(sd) else f"{sd:.{digits}f}"
    return f"{mean:.{digits}f} ± {sd_s}"
