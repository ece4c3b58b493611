"""The report's "Scenarios" section (``docs/scenarios.md``): for the runs that have a
``<prefix>_scenario.yaml`` (robot failures, communication model), a table of the failure
impact and delivered share per run and per setting, and one figure per (map, team size,
scenario) of the graph idleness over time, mean over seeds per algorithm, with the failure
times marked."""
import logging
import os

import numpy as np
from matplotlib.figure import Figure

from patrolling_sim.report import html as H
from patrolling_sim.report.plots import TIME_LABEL, algorithm_colors, save, slug
from patrolling_sim.model import map_bundle
from patrolling_sim.monitor.metrics import graph_idleness_series
from patrolling_sim.scenarios.scenario import read_scenario
from patrolling_sim.scenarios.scenario import scenario_columns

log = logging.getLogger(__name__)


def _fmt(x, nd=1):
    return "n/a" if x is None or H.is_nan(x) else f"{x:.{nd}f}"


def collect(runs):
    """[(run, scenario doc, columns, n_vertices)] of the runs with a scenario file."""
    out = []
    for r in runs:
        try:
            doc = read_scenario(r.prefix)
        except ValueError as e:
            log.warning("%s", e)
            continue
        if doc is None:
            continue
        try:
            n = map_bundle.vertex_count(r.info["map"])
        except Exception:               # a map that is not shipped: no impact columns
            n = None
        cols = scenario_columns(r.prefix, n, float(r.info["sim_duration"])) if n else {}
        out.append((r, doc, cols, n))
    return out


def idleness_over_time_figure(title, curves, failure_times):
    """Graph idleness over time: one line per algorithm (mean over its runs), a vertical
    line at every failure time."""
    fig = Figure(figsize=(10.0, 4.0))
    ax = fig.add_subplot(1, 1, 1)
    colors = algorithm_colors(sorted(curves))
    for alg in sorted(curves):
        t, y = curves[alg]
        ax.plot(t, y, lw=1.2, color=colors[alg], label=alg)
    for k, tf in enumerate(sorted(set(failure_times))):
        ax.axvline(tf, color="red", ls="--", lw=1.0, label="failure" if k == 0 else None)
    ax.set_xlabel(TIME_LABEL)
    ax.set_ylabel("graph idleness (s), mean over vertices")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.set_ylim(bottom=0)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0)
    fig.tight_layout()
    return fig


def _summary_table(groups):
    """Mean over the runs of each (map, N, comm, schedule, algorithm)."""
    def mean(vals):
        vals = [v for v in vals if v is not None and not H.is_nan(v)]
        return sum(vals) / len(vals) if vals else None
    rows = []
    for (mp, n_r, comm, sched), members in sorted(groups.items(), key=lambda kv: str(kv[0])):
        by_alg = {}
        for r, doc, c, n in members:
            by_alg.setdefault(r.info["algorithm"], []).append(c)
        for alg in sorted(by_alg):
            cs = by_alg[alg]
            settled = [c.get("settle_time") for c in cs if c.get("settle_time") is not None]
            rows.append([mp, str(n_r), comm, sched, alg, str(len(cs)),
                         _fmt(mean([c.get("delivered_share") for c in cs]), 3),
                         _fmt(mean([c.get("idl_before") for c in cs])),
                         _fmt(mean([c.get("idl_after") for c in cs])),
                         f"{len(settled)}/{len(cs)}", _fmt(mean(settled), 0)])
    header = ["map", "N", "comm", "failures", "algorithm", "runs", "delivered share",
              "idleness before (s)", "after (s)", "settled", "settle time (s)"]
    return H.table(header, rows, text_cols=(0, 2, 3, 4))


def scenario_section(runs, out_dir):
    """(html, files) of the section, or None if no run has a scenario file."""
    items = collect(runs)
    if not items:
        return None
    rows, groups = [], {}
    for r, doc, c, n in items:
        rows.append([r.run_id, r.info["algorithm"], str(r.info["team_size"]), doc["comm"],
                     doc.get("schedule", "none"), str(len(doc["failures"])),
                     _fmt(c.get("delivered_share"), 3), _fmt(c.get("idl_before")),
                     _fmt(c.get("idl_after")), _fmt(c.get("settle_time"), 0)])
        key = (r.info["map"], r.info["team_size"], doc["comm"], doc.get("schedule", "none"))
        groups.setdefault(key, []).append((r, doc, c, n))
    header = ["run", "algorithm", "N", "comm", "failures (schedule)", "failed",
              "delivered share", "idleness before (s)", "after (s)", "settle time (s)"]
    body = ("<p>Runs with a scenario (docs/scenarios.md): idleness is the graph idleness "
            "(mean instantaneous idleness over all vertices), around the first failure; "
            "<i>before</i>: its mean over the 600 s before it; <i>after</i>: its settled "
            "level, the mean over the last 600 s before the next failure or the end; settle "
            "time: from when its trailing 300 s average stays within 10 % of <i>after</i>."
            "</p>")
    body += _summary_table(groups)
    body += "<details><summary>every run</summary>"
    body += H.table(header, rows, text_cols=(0, 1, 3, 4)) + "</details>"
    files = []
    for k, ((mp, n_r, comm, sched), members) in enumerate(
            sorted(groups.items(), key=lambda kv: str(kv[0]))):
        curves, per_alg, fails = {}, {}, []
        for r, doc, c, n in members:
            if r.visits is None or not n:
                continue
            dur = float(r.info["sim_duration"])
            t, y = graph_idleness_series(r.visits, n, dur, step=5.0)
            per_alg.setdefault(r.info["algorithm"], []).append((t, y))
            fails += [float(f["t_fail"]) for f in doc["failures"]]
        for alg, series in per_alg.items():
            m = min(len(t) for t, _ in series)
            curves[alg] = (series[0][0][:m], np.mean([y[:m] for _, y in series], axis=0))
        if not curves:
            continue
        title = f"{mp}, {n_r} robots, comm {comm}, failures {sched}"
        path = os.path.join(out_dir, f"scenario_{k}_{slug(mp, n_r)}.png")
        save(idleness_over_time_figure(title, curves, fails), path)
        files.append(path)
        body += H.image(path, title + " (mean over seeds; dashed: failure times)")
    return body, files
