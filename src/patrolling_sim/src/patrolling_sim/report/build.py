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
  runs have a ``_scenario.yaml`` (section "Scenarios", :mod:`.scenarios`).
"""
import datetime
import logging
import os

import numpy as np
import pandas as pd

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.report import html as H
from patrolling_sim.report import plots
from patrolling_sim.report.loading import load_runs
from patrolling_sim.report.stats import pvalue_matrices, significance
from patrolling_sim.report.table import (METRIC_LABELS, METRICS, fmt_mean_sd, group_columns, run_table,
                    summary_table, varying_settings)
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.model.graph import load_graph
from patrolling_sim.monitor import run_status as rs
from patrolling_sim.monitor.run_status import silence_warning
from patrolling_sim.planning.references import references
from patrolling_sim.report.scenarios import scenario_section
from spqrel_nav_lite.mapio import load_map

log = logging.getLogger(__name__)


def _settings_label(row, settings):
    names = {"nav_module": "nav", "initial_positions": "initpos", "goal_wait": "wait",
             "comm_delay": "delay"}
    return " ".join(f"{names[s]}={row[s]}" for s in settings)


def _load_map(name, cache, warnings):
    if name in cache:
        return cache[name]
    try:
        yaml_path, graph_path = paths.map_files(name)
        occ = load_map(yaml_path)
        G = load_graph(graph_path, warn=False)
        cache[name] = (occ, G)
    except PatrolInputError as e:
        warnings.append(f"map '{name}': no heat map ({e})")
        cache[name] = None
    return cache[name]


def _references(name, n, cache, ref_cache):
    """The theoretical references of map ``name`` for ``n`` robots at 1 m/s
    (:mod:`patrolling_sim.planning.references`), None if the map cannot be read."""
    key = (name, int(n))
    if key not in ref_cache:
        loaded = _load_map(name, cache, [])
        if loaded is None:
            ref_cache[key] = None
        else:
            ref_cache[key] = references(PatrolGraph(loaded[1]), int(n), 1.0, name)
    return ref_cache[key]


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


def build_report(dirs, out_dir, title=None, run_plots=True, include_fail=False):
    """Write the report for the runs under ``dirs`` into ``out_dir``. Only runs that ended
    normally are averaged (see :func:`select_runs`); the others are listed as excluded.

    Returns:
        dict with ``runs`` (number), ``per_run`` / ``summary`` / ``pvalues`` DataFrames,
        ``files`` (paths written) and ``warnings`` (lines).

    Raises:
        PatrolInputError: a bad input path or a malformed result file.
    """
    all_runs, warnings = load_runs(dirs, slim=not run_plots)
    runs, excluded = select_runs(all_runs, include_fail)
    if not runs:
        counts = {}
        for r, _ in excluded:
            counts[r.status] = counts.get(r.status, 0) + 1
        raise PatrolInputError(
            "argument RESULTS_DIR: no complete run to report ("
            + ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
            + "; only TIMEOUT/CYCLES/STOPPED runs are used, FAIL with --include-fail)")
    for r in runs:              # a robot that stood still for minutes in a complete run
        line = silence_warning(r.silences, r.dead_robot_timeout)
        if line:
            warnings.append(f"{r.prefix}: {line}")
    inferred = [r for r in runs if r.status_note.startswith("no _run.yaml")]
    if inferred:
        warnings.append(f"{len(inferred)} run(s) without _run.yaml (older results): their "
                        f"status was inferred from info.csv")
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise PatrolInputError(f"argument --out: '{out_dir}' exists and is not a directory")
    try:
        os.makedirs(os.path.join(out_dir, "runs") if run_plots else out_dir, exist_ok=True)
    except OSError as e:
        raise PatrolInputError(f"argument --out: cannot create '{out_dir}' ({e.strerror})") from None
    title = title or "Patrolling results"
    files = []

    per_run = run_table(runs)
    for _, r in per_run.iterrows():
        if r["samples"] == 0:
            warnings.append(f"{r['prefix']}_idleness.csv: no idleness samples")
        elif not r["idl_avg_agrees"]:
            warnings.append(f"{r['prefix']}_info.csv: idl_avg {r['info_idl_avg']:.1f} differs "
                            f"from the mean of the idleness samples {r['avg_idleness']:.2f} "
                            f"(the table uses the samples)")
    per_run_all = run_table(all_runs)
    summary = summary_table(per_run, per_run_all)
    excluded_df = pd.DataFrame([{"run_id": r.run_id, "prefix": r.prefix,
                                 "algorithm": r.info["algorithm"], "N": r.info["team_size"],
                                 "map": r.info["map"], "status": r.status,
                                 "sim_duration": r.info["sim_duration"], "why": why}
                                for r, why in excluded],
                               columns=["run_id", "prefix", "map", "N", "algorithm", "status",
                                        "sim_duration", "why"])
    sig = significance(runs, per_run)
    settings = varying_settings(per_run)
    gcols = group_columns(per_run)
    cmp_cols = [c for c in gcols if c != "algorithm"]
    by_prefix = {r.prefix: r for r in runs}
    colors = plots.algorithm_colors(per_run["algorithm"])

    summary.to_csv(os.path.join(out_dir, "summary.csv"), index=False, float_format="%.6g")
    per_run.to_csv(os.path.join(out_dir, "runs.csv"), index=False, float_format="%.6g")
    sig.to_csv(os.path.join(out_dir, "pairwise_pvalues.csv"), index=False, float_format="%.6g")
    excluded_df.to_csv(os.path.join(out_dir, "excluded.csv"), index=False,
                       float_format="%.6g")
    files += [os.path.join(out_dir, f) for f in ("summary.csv", "runs.csv",
                                                 "pairwise_pvalues.csv", "excluded.csv")]

    def samples_of(df):
        parts = [by_prefix[p].samples["Idleness"].to_numpy(dtype=float) for p in df["prefix"]]
        return np.concatenate(parts) if parts else np.array([])

    # --- figures -------------------------------------------------------------------
    box_figs, heat_figs, hist_figs, time_figs = [], [], [], []
    map_cache, ref_cache = {}, {}
    for mp, gm in per_run.groupby("map", sort=True):
        boxes, refs = [], []
        for key, g in gm.groupby(settings + ["N", "algorithm"], sort=True):
            row = g.iloc[0]
            lab = f"{row['algorithm']}\nN={row['N']}"
            if settings:
                lab += "\n" + _settings_label(row, settings)
            boxes.append((lab, row["algorithm"], samples_of(g)))
            refs.append(_references(mp, row["N"], map_cache, ref_cache))
        fig = plots.boxplot_figure(f"Idleness on map {mp} (all samples of all runs)", boxes,
                                   colors, refs)
        path = plots.save(fig, os.path.join(out_dir, plots.slug("boxplot", mp) + ".png"))
        box_figs.append((path, f"Idleness samples per algorithm and team size, map {mp}"))

    cache = {}
    for key, g in per_run.groupby(cmp_cols, sort=True, dropna=False):
        row = g.iloc[0]
        desc = f"map {row['map']}, N={row['N']}"
        if settings:
            desc += ", " + _settings_label(row, settings)
        name_parts = [row["map"], row["N"]] + [row[s] for s in settings]
        algs = sorted(g["algorithm"].unique())
        series = [(a, a, samples_of(g[g["algorithm"] == a])) for a in algs]
        fig = plots.histogram_figure(f"Idleness distribution, {desc}", series, colors)
        path = plots.save(fig, os.path.join(out_dir, plots.slug("histogram", *name_parts) + ".png"))
        hist_figs.append((path, f"Idleness histogram, {desc}"))

        loaded = _load_map(row["map"], cache, warnings)
        if loaded is None:
            continue
        occ, G = loaded
        panels = []
        bad = None
        for a in algs:
            smp = pd.concat([by_prefix[p].samples for p in g[g["algorithm"] == a]["prefix"]])
            if len(smp) and (smp["Node"].max() >= G.number_of_nodes()):
                bad = (a, int(smp["Node"].max()))
                break
            avg = smp.groupby("Node")["Idleness"].mean().to_dict() if len(smp) else {}
            nruns = int((g["algorithm"] == a).sum())
            panels.append((f"{a} ({nruns} run{'s' if nruns != 1 else ''})",
                           {int(k): float(v) for k, v in avg.items()}))
        if bad:
            warnings.append(f"map '{row['map']}': runs of {bad[0]} visit vertex {bad[1]} but "
                            f"the graph has {G.number_of_nodes()} vertices: no heat map")
            continue
        fig = plots.heatmap_figure(f"Average idleness per vertex, {desc}", occ, G, panels)
        path = plots.save(fig, os.path.join(out_dir, plots.slug("heatmap", *name_parts) + ".png"))
        heat_figs.append((path, f"Per-vertex average idleness (pooled samples of all runs), {desc}"))

    used = set()
    for _, r in (per_run.iterrows() if run_plots else ()):
        run = by_prefix[r["prefix"]]
        base = plots.slug("time", r["map"], r["N"], r["algorithm"], r["hostname"],
                          os.path.basename(r["prefix"]))
        name, k = base, 1
        while name in used:
            k += 1
            name = f"{base}_{k}"
        used.add(name)
        t = (f"{r['algorithm']}, map {r['map']}, N={r['N']}, run {r['hostname']}/"
             f"{os.path.basename(r['prefix'])}")
        fig = plots.timeplot_figure(t, run.samples, r["N"])
        path = plots.save(fig, os.path.join(out_dir, "runs", name + ".png"))
        time_figs.append((path, f"Idleness samples over time, {t}"))
    files += [p for p, _ in box_figs + heat_figs + hist_figs + time_figs]

    # --- HTML ----------------------------------------------------------------------
    sections = []
    intro = (f"<p>{len(runs)} run(s) from {', '.join(H.esc(d) for d in dirs)}"
             + (f" ({len(excluded)} more excluded: they did not end normally, see "
                f"<i>Excluded runs</i>)" if excluded else "") + ". Generated "
             f"{H.esc(datetime.datetime.now().strftime('%Y-%m-%d %H:%M:%S'))}.</p>"
             "<p class='note'>Idleness metrics come from the idleness.csv samples (one per "
             "vertex visit after the first); complete cycles and interference rate (per "
             "minute) from info.csv. Values are mean ± sample SD over runs (n/a for one "
             "run).</p>")
    if warnings:
        intro += ("<details open><summary class='warn'>" + f"{len(warnings)} warning(s)"
                  "</summary><ul>" + "".join(f"<li class='warn'>{H.esc(w)}</li>"
                                             for w in warnings) + "</ul></details>")
    sections.append((None, intro))

    lead = [c for c in gcols]
    header = lead + ["runs", "statuses (all loaded runs)"] + [METRIC_LABELS[m] for m in METRICS]
    rows = []
    for _, s in summary.iterrows():
        rows.append([str(s[c]) for c in lead] + [str(s["runs"]), str(s["statuses"])] +
                    [fmt_mean_sd(s[f"{m}_mean"], s[f"{m}_sd"],
                                 2 if m == "interference_rate" else 1) for m in METRICS])
    sections.append(("Summary", H.table(header, rows, text_cols=range(len(lead) + 2))))
    if excluded:
        sections.append(("Excluded runs", "<p class='note'>Not averaged: these runs did not "
                         "end normally (their metrics cover a truncated or failed run).</p>" +
                         H.table(["run", "algorithm", "N", "status", "sim time (s)", "why"],
                                 [[r.run_id, r.info["algorithm"], str(r.info["team_size"]),
                                   r.status, f"{r.info['sim_duration']:.1f}", why]
                                  for r, why in excluded], text_cols=(0, 1, 3, 5))))

    if sig.empty:
        body = ("<p>No comparison: significance tests need at least two algorithms with the "
                "same map and team size"
                + (" and settings" if settings else "") + ".</p>")
    else:
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
    sections.append(("Significance", body))

    sections.append(("Idleness per algorithm and team size",
                     "".join(H.image(p, c) for p, c in box_figs)))
    sections.append(("Per-vertex idleness on the map",
                     "".join(H.image(p, c) for p, c in heat_figs) or
                     "<p>No heat map (see warnings).</p>"))
    sections.append(("Idleness histograms", "".join(H.image(p, c) for p, c in hist_figs)))

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
    sections.append(("Runs", H.table(rheader, rrows, text_cols=(0, 1, 10, 11))))
    scen = scenario_section(runs, out_dir)
    if scen is not None:
        sections.append(("Scenarios", scen[0]))
        files += scen[1]
    if run_plots:
        sections.append(("Idleness over time (one figure per run)",
                         "<details open><summary>show / hide</summary>" +
                         "".join(H.image(p, c) for p, c in time_figs) + "</details>"))

    html_path = os.path.join(out_dir, "report.html")
    with open(html_path, "w", encoding="utf-8") as f:
        f.write(H.page(title, sections))
    files.insert(0, html_path)
    return {"runs": len(runs), "per_run": per_run, "summary": summary, "pvalues": sig,
            "files": files, "warnings": warnings, "excluded": excluded_df}
