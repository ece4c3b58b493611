"""The report's figure files: which figures a report has, the runs' samples each one
pools, and their PNG files in the report folder (drawn by :mod:`.plots`). Part of
:func:`patrolling_sim.report.build.build_report`.

Every function here returns ``[(path, caption)]``, the figures in the order written."""
import os

import numpy as np
import pandas as pd

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.model.graph import load_graph
from patrolling_sim.planning.references import references
from patrolling_sim.report import plots
from spqrel_nav_lite.mapio import load_map


def settings_label(row, settings):
    """``nav=... initpos=...``: the values in ``row`` of the varying ``settings`` (columns
    of the per-run table), with short names."""
    names = {"nav_module": "nav", "initial_positions": "initpos", "goal_wait": "wait",
             "comm_delay": "delay"}
    return " ".join(f"{names[s]}={row[s]}" for s in settings)


def load_map_cached(name, cache, warnings):
    """(occupancy map, graph) of map ``name``, read once per ``cache`` (a dict); None if the
    map cannot be read, with a line appended to ``warnings`` (once per cache)."""
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


def map_references(name, n, cache, ref_cache):
    """The theoretical references of map ``name`` for ``n`` robots at 1 m/s
    (:mod:`patrolling_sim.planning.references`), None if the map cannot be read; computed
    once per ``ref_cache``, the map read once per ``cache``."""
    key = (name, int(n))
    if key not in ref_cache:
        loaded = load_map_cached(name, cache, [])
        if loaded is None:
            ref_cache[key] = None
        else:
            ref_cache[key] = references(PatrolGraph(loaded[1]), int(n), 1.0, name)
    return ref_cache[key]


def samples_of(df, by_prefix):
    """All idleness samples (a float array) of the runs listed in ``df`` (rows of the
    per-run table), looked up by prefix in ``by_prefix``."""
    parts = [by_prefix[p].samples["Idleness"].to_numpy(dtype=float) for p in df["prefix"]]
    return np.concatenate(parts) if parts else np.array([])


def boxplot_figures(per_run, settings, by_prefix, colors, out_dir):
    """One box plot per map (``boxplot_<map>.png``): the idleness samples of each (settings,
    N, algorithm) group, with the map's theoretical references."""
    figs = []
    map_cache, ref_cache = {}, {}
    for mp, gm in per_run.groupby("map", sort=True):
        boxes, refs = [], []
        for key, g in gm.groupby(settings + ["N", "algorithm"], sort=True):
            row = g.iloc[0]
            lab = f"{row['algorithm']}\nN={row['N']}"
            if settings:
                lab += "\n" + settings_label(row, settings)
            boxes.append((lab, row["algorithm"], samples_of(g, by_prefix)))
            refs.append(map_references(mp, row["N"], map_cache, ref_cache))
        fig = plots.boxplot_figure(f"Idleness on map {mp} (all samples of all runs)", boxes,
                                   colors, refs)
        path = plots.save(fig, os.path.join(out_dir, plots.slug("boxplot", mp) + ".png"))
        figs.append((path, f"Idleness samples per algorithm and team size, map {mp}"))
    return figs


def group_figures(per_run, cmp_cols, settings, by_prefix, colors, out_dir, warnings):
    """(heat maps, histograms): for each group of runs with the same ``cmp_cols`` values
    (map, N, settings), a histogram of its algorithms' idleness samples
    (``histogram_<map>_<N>[...].png``), then, if the map can be read and its graph has the
    vertices the runs visit, a heat map of the per-vertex average idleness
    (``heatmap_<map>_<N>[...].png``); why a heat map is missing is appended to
    ``warnings``."""
    heat_figs, hist_figs = [], []
    cache = {}
    for key, g in per_run.groupby(cmp_cols, sort=True, dropna=False):
        row = g.iloc[0]
        desc = f"map {row['map']}, N={row['N']}"
        if settings:
            desc += ", " + settings_label(row, settings)
        name_parts = [row["map"], row["N"]] + [row[s] for s in settings]
        algs = sorted(g["algorithm"].unique())
        series = [(a, a, samples_of(g[g["algorithm"] == a], by_prefix)) for a in algs]
        fig = plots.histogram_figure(f"Idleness distribution, {desc}", series, colors)
        path = plots.save(fig, os.path.join(out_dir, plots.slug("histogram", *name_parts)
                                            + ".png"))
        hist_figs.append((path, f"Idleness histogram, {desc}"))
        loaded = load_map_cached(row["map"], cache, warnings)
        if loaded is None:
            continue
        heat = _heatmap(g, algs, loaded, desc, name_parts, by_prefix, out_dir, warnings)
        if heat is not None:
            heat_figs.append(heat)
    return heat_figs, hist_figs


def _heatmap(g, algs, loaded, desc, name_parts, by_prefix, out_dir, warnings):
    """(path, caption) of the heat map of the runs ``g`` of one group (one panel per
    algorithm of ``algs``: its pooled samples' average idleness per vertex) on the
    (occupancy map, graph) ``loaded``; None, with a line appended to ``warnings``, if some
    run visits a vertex the graph does not have."""
    occ, G = loaded
    panels = []
    for a in algs:
        smp = pd.concat([by_prefix[p].samples for p in g[g["algorithm"] == a]["prefix"]])
        if len(smp) and (smp["Node"].max() >= G.number_of_nodes()):
            warnings.append(f"map '{g.iloc[0]['map']}': runs of {a} visit vertex "
                            f"{int(smp['Node'].max())} but the graph has "
                            f"{G.number_of_nodes()} vertices: no heat map")
            return None
        avg = smp.groupby("Node")["Idleness"].mean().to_dict() if len(smp) else {}
        nruns = int((g["algorithm"] == a).sum())
        panels.append((f"{a} ({nruns} run{'s' if nruns != 1 else ''})",
                       {int(k): float(v) for k, v in avg.items()}))
    fig = plots.heatmap_figure(f"Average idleness per vertex, {desc}", occ, G, panels)
    path = plots.save(fig, os.path.join(out_dir, plots.slug("heatmap", *name_parts) + ".png"))
    return path, f"Per-vertex average idleness (pooled samples of all runs), {desc}"


def time_figures(per_run, by_prefix, out_dir):
    """One figure per run of idleness samples over time (``runs/time_<run>.png``, names made
    unique with ``_2``, ``_3``, ...)."""
    figs = []
    used = set()
    for _, r in per_run.iterrows():
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
        figs.append((path, f"Idleness samples over time, {t}"))
    return figs
