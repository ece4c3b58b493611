"""Assemble the report: load runs, compute tables and tests, draw figures, write files.

Output files in ``out_dir``:

- ``report.html``          self-contained page (figures embedded as base64 PNG);
- ``summary.csv``          summary table, numeric columns (``*_mean``, ``*_sd``; sd empty
  for a single run);
- ``runs.csv``             one row per run (metrics, info.csv check);
- ``pairwise_pvalues.csv`` Kruskal-Wallis and pairwise Mann-Whitney/Holm results (header
  only when no group has two algorithms);
- ``boxplot_<map>.png``, ``heatmap_<map>_<N>[...].png``, ``histogram_<map>_<N>[...].png``,
  ``runs/time_<run>.png`` (unless ``run_plots`` is false).
- ``scenario_<k>_<map>_<N>.png``: graph idleness over time with failure times marked, when
  runs have a ``_scenario.yaml`` (section "Scenarios", :mod:`patrolling_sim.report.scenarios`).
"""
import collections
import datetime
import logging
import os

import pandas as pd

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.report import figures
from patrolling_sim.report import html as H
from patrolling_sim.report import plots
from patrolling_sim.report.loading import load_runs
from patrolling_sim.report.result_sets import UNREADABLE, UnreadableRun
from patrolling_sim.report.stats import pvalue_matrices, significance
from patrolling_sim.report.table import (METRIC_LABELS, METRICS, fmt_mean_sd, group_columns,
                                         run_table, summary_table, varying_settings)
from patrolling_sim.monitor import run_status as rs
from patrolling_sim.monitor.run_status import silence_warning
from patrolling_sim.report.scenarios import scenario_section

log = logging.getLogger(__name__)


def select_runs(runs, include_fail=False):
    """(used, excluded): a report averages only runs that ended normally (TIMEOUT, CYCLES,
    STOPPED; FAIL too with ``include_fail``); ``excluded`` is [(run, why)]."""
    ok = set(rs.NORMAL_ENDS) | ({rs.FAIL} if include_fail else set())
    used, excluded = [], []
    for r in runs:
        if r.status in ok:
            used.append(r)
        else:
            why = f"status {r.status or '?'}"
            if r.status == rs.FAIL:
                why += " (give --include-fail to use it)"
            if r.status_note:
                why += f": {r.status_note}"
            excluded.append((r, why))
    return used, excluded


def _no_complete_run(excluded):
    """The PatrolInputError of a report without a complete run: the excluded runs counted
    per status."""
    counts = {}
    for r, _ in excluded:
        counts[r.status] = counts.get(r.status, 0) + 1
    unreadable = [why for r, why in excluded if r.status == UNREADABLE]
    return PatrolInputError(
        "argument RESULTS_DIR: no complete run to report ("
        + ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
        + "; only TIMEOUT/CYCLES/STOPPED runs are used, FAIL with --include-fail)"
        + (f"; first unreadable: {unreadable[0]}" if unreadable else ""))


def _add_run_warnings(runs, warnings):
    """Append to ``warnings`` a line per run of ``runs`` with a robot that stood still for
    minutes, then one for the runs whose status was inferred (no ``_run.yaml``)."""
    for r in runs:
        line = silence_warning(r.silences, r.dead_robot_timeout)
        if line:
            warnings.append(f"{r.prefix}: {line}")
    inferred = [r for r in runs if r.status_note.startswith("no _run.yaml")]
    if inferred:
        warnings.append(f"{len(inferred)} run(s) without _run.yaml (older results): their "
                        f"status was inferred from info.csv")


def _make_out_dir(out_dir, run_plots):
    """Create ``out_dir`` (and its ``runs`` folder with ``run_plots``). Raises
    PatrolInputError: it exists and is not a directory, or cannot be created."""
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise PatrolInputError(f"argument --out: '{out_dir}' exists and is not a directory")
    try:
        os.makedirs(os.path.join(out_dir, "runs") if run_plots else out_dir, exist_ok=True)
    except OSError as e:
        raise PatrolInputError(f"argument --out: cannot create '{out_dir}' ({e.strerror})") \
            from None


def _add_sample_warnings(per_run, warnings):
    """Append to ``warnings`` a line per run of the per-run table without idleness samples
    or whose info.csv average disagrees with its samples' mean."""
    for _, r in per_run.iterrows():
        if r["samples"] == 0:
            warnings.append(f"{r['prefix']}_idleness.csv: no idleness samples")
        elif not r["idl_avg_agrees"]:
            warnings.append(f"{r['prefix']}_info.csv: idl_avg {r['info_idl_avg']:.1f} differs "
                            f"from the mean of the idleness samples {r['avg_idleness']:.2f} "
                            f"(the table uses the samples)")


def _excluded_table(excluded):
    """The DataFrame of the excluded runs ``[(run, why)]`` (``excluded.csv``)."""
    return pd.DataFrame([{"run_id": r.run_id, "prefix": r.prefix,
                          "algorithm": r.info["algorithm"], "N": r.info["team_size"],
                          "map": r.info["map"], "status": r.status,
                          "sim_duration": r.info["sim_duration"], "why": why}
                         for r, why in excluded],
                        columns=["run_id", "prefix", "map", "N", "algorithm", "status",
                                 "sim_duration", "why"])


def _write_tables(out_dir, summary, per_run, sig, excluded_df):
    """Write ``summary.csv``, ``runs.csv``, ``pairwise_pvalues.csv`` and ``excluded.csv``
    into ``out_dir``; returns their paths in that order."""
    summary.to_csv(os.path.join(out_dir, "summary.csv"), index=False, float_format="%.6g")
    per_run.to_csv(os.path.join(out_dir, "runs.csv"), index=False, float_format="%.6g")
    sig.to_csv(os.path.join(out_dir, "pairwise_pvalues.csv"), index=False, float_format="%.6g")
    excluded_df.to_csv(os.path.join(out_dir, "excluded.csv"), index=False,
                       float_format="%.6g")
    return [os.path.join(out_dir, f) for f in ("summary.csv", "runs.csv",
                                               "pairwise_pvalues.csv", "excluded.csv")]


def _intro(runs, dirs, excluded, warnings):
    """The report's opening HTML: what was loaded and when, how the metrics are computed,
    and the warnings (if any)."""
    reasons = collections.Counter(r.status for r, _ in excluded)
    intro = (f"<p>{len(runs) + len(excluded)} result set(s) found in "
             f"{', '.join(H.esc(d) for d in dirs)}: {len(runs)} used"
             + (f", {len(excluded)} excluded (" + ", ".join(
                 f"{n} {H.esc(s or '?')}" for s, n in sorted(reasons.items()))
                + "; see <i>Excluded runs</i>)" if excluded else "") + ". Generated "
             f"{H.esc(datetime.datetime.now().strftime('%Y-%m-%d %H:%M:%S'))}.</p>"
             "<p class='note'>Idleness metrics come from the idleness.csv samples (one per "
             "vertex visit after the first); complete cycles and interference rate (per "
             "minute) from info.csv. Values are mean ± sample SD over runs (n/a for one "
             "run).</p>")
    if warnings:
        intro += ("<details open><summary class='warn'>" + f"{len(warnings)} warning(s)"
                  "</summary><ul>" + "".join(f"<li class='warn'>{H.esc(w)}</li>"
                                             for w in warnings) + "</ul></details>")
    return intro


def _summary_html(summary, gcols):
    """The summary table's HTML: one row per group (``gcols``), mean ± SD per metric."""
    lead = [c for c in gcols]
    header = lead + ["runs", "statuses (all loaded runs)"] + [METRIC_LABELS[m] for m in METRICS]
    rows = []
    for _, s in summary.iterrows():
        rows.append([str(s[c]) for c in lead] + [str(s["runs"]), str(s["statuses"])] +
                    [fmt_mean_sd(s[f"{m}_mean"], s[f"{m}_sd"],
                                 2 if m == "interference_rate" else 1) for m in METRICS])
    return H.table(header, rows, text_cols=range(len(lead) + 2))


def _excluded_html(excluded):
    """The HTML of the excluded runs ``[(run, why)]``: a note and their table."""
    return ("<p class='note'>Not averaged: these runs did not end normally (their metrics "
            "cover a truncated or failed run), or their result files could not be read "
            "(UNREADABLE: a malformed or partial file, or no info.csv).</p>" +
            H.table(["run", "algorithm", "N", "status", "sim time (s)", "why"],
                    [[r.run_id, r.info["algorithm"], str(r.info["team_size"]),
                      r.status, f"{r.info['sim_duration']:.1f}", why]
                     for r, why in excluded], text_cols=(0, 1, 3, 5)))


def _significance_html(sig, settings, cmp_cols):
    """The significance section's HTML: per group (``cmp_cols``) the Kruskal-Wallis result
    and the matrix of Holm-adjusted pairwise p-values (shaded below 0.05), or why there is
    no comparison."""
    if sig.empty:
        return ("<p>No comparison: significance tests need at least two algorithms with the "
                "same map and team size"
                + (" and settings" if settings else "") + ".</p>")
    body = ("<p class='note'>Kruskal–Wallis test over all algorithms of a group, then "
            "pairwise two-sided Mann–Whitney U tests with Holm correction (matrix: "
            "adjusted p-values, shaded below 0.05). Basis <b>run means</b>: each run's "
            "mean idleness is one observation (used when every algorithm has ≥ 2 runs); "
            "<b>samples</b>: every idleness sample is one observation (some algorithm "
            "has a single run; the test then compares those runs).</p>")
    for key, basis, h, kp, m in pvalue_matrices(sig, cmp_cols):
        desc = ", ".join(f"{k}={v}" for k, v in key.items())
        hs = "n/a" if H.is_nan(h) else f"{h:.3f}"
        body += (f"<h3>{H.esc(desc)}</h3><p>basis: {H.esc(basis)}; Kruskal–Wallis "
                 f"H = {hs}, p = {kp:.4g}</p>")
        algs = list(m.index)
        mrows = [[a] + ["" if H.is_nan(m.loc[a, b]) else f"{m.loc[a, b]:.4g}" for b in algs]
                 for a in algs]

        def cls(i, j, m=m, algs=algs):
            if j == 0:
                return None
            v = m.iloc[i, j - 1]
            return "sig" if not H.is_nan(v) and v < 0.05 else None
        body += H.table(["p (Holm)"] + algs, mrows, text_cols=(0,), cell_class=cls)
    return body


def _runs_html(per_run):
    """The HTML table of the per-run table: one row per run."""
    rheader = ["run", "algorithm", "N", "samples", "avg idleness (s)", "info.csv idl_avg",
               "max idleness (s)", "cycles", "interf. rate (1/min)", "sim time (s)",
               "longest silence (s)", "status"]
    rrows = []
    for _, r in per_run.iterrows():
        rrows.append([r["run_id"], r["algorithm"], str(r["N"]), str(r["samples"]),
                      "n/a" if H.is_nan(r["avg_idleness"]) else f"{r['avg_idleness']:.2f}",
                      ("n/a" if H.is_nan(r["info_idl_avg"]) else f"{r['info_idl_avg']:.1f}")
                      + ("" if r["idl_avg_agrees"] else " (≠)"),
                      "n/a" if H.is_nan(r["max_idleness"]) else f"{r['max_idleness']:.1f}",
                      str(r["complete_cycles"]), f"{r['interference_rate']:.2f}",
                      f"{r['sim_duration']:.1f}",
                      "n/a" if H.is_nan(r["longest_silence"]) else
                      f"{r['longest_silence']:.1f} (robot {r['longest_silence_robot']})",
                      r["status"]])
    return H.table(rheader, rrows, text_cols=(0, 1, 10, 11))


def _images(figs):
    """The HTML of the figures ``[(path, caption)]``, in order."""
    return "".join(H.image(p, c) for p, c in figs)


def build_report(dirs, out_dir, title=None, run_plots=True, include_fail=False):
    """Write the report for the runs under ``dirs`` into ``out_dir``. Only runs that ended
    normally are averaged (see :func:`select_runs`); the others are listed as excluded.

    Returns:
        dict with ``runs`` (number), ``per_run`` / ``summary`` / ``pvalues`` /
        ``excluded`` DataFrames, ``files`` (paths written, the HTML page first) and
        ``warnings`` (lines).

    Raises:
        PatrolInputError: a bad input path or a malformed result file, no complete run,
        or an output folder that cannot be made.
    """
    all_runs, warnings, unreadable = load_runs(dirs, slim=not run_plots)
    runs, excluded = select_runs(all_runs, include_fail)
    excluded += [(UnreadableRun(p), why) for p, why in unreadable]
    if not runs:
        raise _no_complete_run(excluded)
    _add_run_warnings(runs, warnings)
    _make_out_dir(out_dir, run_plots)
    title = title or "Patrolling results"
    per_run = run_table(runs)
    _add_sample_warnings(per_run, warnings)
    summary = summary_table(per_run, run_table(all_runs))
    excluded_df = _excluded_table(excluded)
    sig = significance(runs, per_run)
    settings = varying_settings(per_run)
    gcols = group_columns(per_run)
    cmp_cols = [c for c in gcols if c != "algorithm"]
    by_prefix = {r.prefix: r for r in runs}
    colors = plots.algorithm_colors(per_run["algorithm"])
    files = _write_tables(out_dir, summary, per_run, sig, excluded_df)

    box_figs = figures.boxplot_figures(per_run, settings, by_prefix, colors, out_dir)
    heat_figs, hist_figs = figures.group_figures(per_run, cmp_cols, settings, by_prefix,
                                                 colors, out_dir, warnings)
    time_figs = figures.time_figures(per_run, by_prefix, out_dir) if run_plots else []
    files += [p for p, _ in box_figs + heat_figs + hist_figs + time_figs]

    sections = [(None, _intro(runs, dirs, excluded, warnings)),
                ("Summary", _summary_html(summary, gcols))]
    if excluded:
        sections.append(("Excluded runs", _excluded_html(excluded)))
    sections += [("Significance", _significance_html(sig, settings, cmp_cols)),
                 ("Idleness per algorithm and team size", _images(box_figs)),
                 ("Per-vertex idleness on the map",
                  _images(heat_figs) or "<p>No heat map (see warnings).</p>"),
                 ("Idleness histograms", _images(hist_figs)),
                 ("Runs", _runs_html(per_run))]
    scen = scenario_section(runs, out_dir)
    if scen is not None:
        sections.append(("Scenarios", scen[0]))
        files += scen[1]
    if run_plots:
        sections.append(("Idleness over time (one figure per run)",
                         "<details open><summary>show / hide</summary>" +
                         _images(time_figs) + "</details>"))
    html_path = os.path.join(out_dir, "report.html")
    with open(html_path, "w", encoding="utf-8") as f:
        f.write(H.page(title, sections))
    files.insert(0, html_path)
    return {"runs": len(runs), "per_run": per_run, "summary": summary, "pvalues": sig,
            "files": files, "warnings": warnings, "excluded": excluded_df}
