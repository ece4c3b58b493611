"""Reference tables: Markdown pages and figures of a campaign's ``runs.csv`` (docs/reference/).

:func:`build_reference_docs` reads a campaign folder (``runs.csv``, and ``provenance.yaml``
if present, see ``docs/campaigns.md``) and returns the pages in memory; :func:`write_docs`
writes them. For every map: per team size, one table algorithm x metrics (mean ± SD over the
seeds of the runs that ended with ``TIMEOUT``, with their count), the theoretical references
of :mod:`patrolling_sim.planning.references` (best closed tour, cyclic ``L/(k v)``,
partition), and one figure (idleness vs team size per algorithm, the references as lines).
Runs not done yet are counted (the pages say PARTIAL); runs that ended otherwise (CYCLES,
FAIL, CRASHED, ERROR ...) are excluded from the means and counted per cell, never mixed in.
Cells where some vertex was never visited in some seed, or whose worst idleness rises with
the team size, are flagged, with their cause from a causes file
(:mod:`patrolling_sim.report.starvation`). Campaigns that re-ran some algorithms replace those
algorithms' runs (:mod:`patrolling_sim.report.reference_sources`), and cells measured against
the original's own agents link their status (:mod:`patrolling_sim.report.fidelity_status`).
The metric definitions are those of ``docs/metrics.md``.
"""
import datetime
import io
import os
import shlex
import sys
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.cli import CliParser
from patrolling_sim.common.cli import run_main
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.model.graph import load_graph
from patrolling_sim.planning.references import references
from patrolling_sim.report import fidelity_status, starvation
from patrolling_sim.report.reference_relink import relinked_files
from patrolling_sim.report.reference_sources import config_columns, display_names
from patrolling_sim.report.reference_sources import merge_sources

#: (runs.csv column, heading, decimals): the columns of every table
METRICS = (("idl_avg", "avg idleness (original) [s]", 1),
           ("time_avg_idleness", "time-avg idleness [s]", 1),
           ("worst_idleness", "worst idleness [s]", 1),
           ("idl_max", "max idleness (original) [s]", 1),
           ("total_visits", "visits", 0))
#: where a measured cell's fidelity status links to (relative to docs/reference/)
FIDELITY_LINK = fidelity_status.MATRIX_LINK
#: the only status averaged: a run that patrolled for the whole duration
USED_STATUS = "TIMEOUT"
NOT_RUN = "NOT_RUN"
CELL = ["map", "robots", "alg"]
REQUIRED = ("map", "robots", "alg", "seed", "status")


@dataclass
class ReferenceDocs:
    """The generated pages: file name -> text (``.md``) or bytes (``.png``)."""
    files: Dict[str, object] = field(default_factory=dict)
    total: int = 0
    done: int = 0
    excluded: int = 0

    @property
    def partial(self):
        return self.done + self.excluded < self.total


def load_runs(campaign_dir: str):
    """``runs.csv`` of ``campaign_dir`` as a DataFrame, checked.

    Raises:
        PatrolInputError: one line naming the folder or file and what is wrong.
    """
    import pandas as pd
    if not os.path.isdir(campaign_dir):
        raise PatrolInputError(f"{campaign_dir}: no such campaign folder")
    path = os.path.join(campaign_dir, "runs.csv")
    if not os.path.isfile(path):
        raise PatrolInputError(f"{path}: no runs.csv (run scripts/campaign.py on the folder "
                               "first)")
    try:
        df = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise PatrolInputError(f"{path}: malformed csv ({str(e).splitlines()[0]})")
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        raise PatrolInputError(f"{path}: missing column(s) {', '.join(missing)}")
    if df.empty:
        raise PatrolInputError(f"{path}: no runs")
    for c in ("robots", "seed"):
        v = pd.to_numeric(df[c], errors="coerce")
        if v.isna().any() or (v != v.round()).any():
            raise PatrolInputError(f"{path}: column {c}: expected integers, got "
                                   f"{df[c][v.isna() | (v != v.round())].iloc[0]!r}")
        df[c] = v.astype(int)
    if df[["map", "alg", "status"]].isna().any().any():
        raise PatrolInputError(f"{path}: empty map, alg or status field")
    if df.duplicated(CELL + ["seed"]).any():
        row = df[df.duplicated(CELL + ["seed"])].iloc[0]
        raise PatrolInputError(f"{path}: run {row['map']}_{row['robots']} {row['alg']} seed "
                               f"{row['seed']} appears twice (the table mixes settings)")
    used = df["status"] == USED_STATUS
    for c, _, _ in METRICS:
        if used.any() and c not in df.columns:
            raise PatrolInputError(f"{path}: missing metric column {c}")
        if c in df.columns:
            # empty is allowed (a run without any visit has no idleness), text is not
            raw = df.loc[used, c]
            v = pd.to_numeric(raw, errors="coerce")
            if (v.isna() & raw.notna()).any():
                raise PatrolInputError(f"{path}: column {c}: a {USED_STATUS} run has a "
                                       f"non-numeric value {raw[v.isna() & raw.notna()].iloc[0]!r}")
            df[c] = pd.to_numeric(df[c], errors="coerce")
    for c in config_columns(df):             # the settings: constant within a cell
        if df.groupby(CELL)[c].nunique(dropna=False).max() > 1:
            raise PatrolInputError(f"{path}: column {c} varies within a map/robots/alg cell; "
                                   "the reference tables need one setting per cell")
    for m in df["map"].unique():
        try:
            paths.map_files(str(m))
        except PatrolInputError as e:
            raise PatrolInputError(f"{path}: map {m!r}: {e}")
    return df


def _fmt(mean, sd, dec):
    if mean != mean:                           # NaN: no run
        return "–"
    s = f"{mean:.{dec}f}"
    return s + (f" ± {sd:.{dec}f}" if sd == sd else "")


def _map_references(map_name, sizes, speed):
    g = PatrolGraph(load_graph(paths.map_files(map_name)[1], warn=False))
    return {n: references(g, int(n), speed, map_name) for n in sizes}


def _figure(map_name, stats, refs, algs):
    """PNG bytes: avg idleness (original's) and worst idleness vs team size per algorithm,
    the cyclic and partition references as lines."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import ScalarFormatter
    import matplotlib
    cmap = matplotlib.colormaps["tab20"]
    fig = Figure(figsize=(12, 4.6))
    FigureCanvasAgg(fig)
    sizes = sorted(refs)
    for ax, col, title in zip(fig.subplots(1, 2), ("idl_avg", "worst_idleness"),
                              ("average idleness (original's)", "worst idleness")):
        for i, a in enumerate(algs):           # 13+ algorithms: 20 colours, 5 markers
            s = stats[stats["alg"] == a].sort_values("robots")
            s = s[s["n"] > 0]
            if len(s):
                ax.errorbar(s["robots"], s[col + "_mean"], yerr=s[col + "_sd"].fillna(0),
                            marker="os^vD"[i % 5], ms=3.5, capsize=2, lw=1,
                            color=cmap(i % 20), label=a)
        ax.plot(sizes, [refs[n].cyclic_idleness for n in sizes], "k--", lw=1.6,
                label="cyclic L/(k v)")
        if col == "worst_idleness":            # a bound on the worst idleness only
            ax.plot(sizes, [refs[n].partition_idleness for n in sizes], "k:", lw=1.6,
                    label="partition")
        ax.set_xlabel("team size")
        ax.set_ylabel("s")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(ScalarFormatter())
        ax.set_xticks(sizes)
        ax.set_title(f"{map_name}: {title}")
        ax.grid(alpha=0.3)
    handles, labels = fig.axes[1].get_legend_handles_labels()
    fig.tight_layout(rect=(0, 0, 0.86, 1))
    fig.legend(handles, labels, fontsize=8, loc="center right")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return buf.getvalue()


def _cell_stats(df, seeds):
    """One row per (map, robots, alg): n used, n excluded, n not run, mean and SD per metric."""
    import pandas as pd
    rows = []
    for (m, n, a), g in df.groupby(CELL, sort=True):
        ok = g[g["status"] == USED_STATUS]
        row = {"map": m, "robots": n, "alg": a, "n": len(ok),
               "not_run": int((g["status"] == NOT_RUN).sum()),
               "excluded": int(((g["status"] != USED_STATUS) & (g["status"] != NOT_RUN)).sum())}
        # a run without any visit has no idleness: averaged over the runs that have one
        row["novisit"] = int(ok["idl_avg"].isna().sum()) if "idl_avg" in ok else 0
        nv = ok["never_visited"].fillna(0) if "never_visited" in ok else pd.Series(dtype=float)
        row["starved"] = int((nv > 0).sum())
        row["starved_most"] = int(nv.max()) if len(nv) else 0
        row["duration"] = float(g["duration"].iloc[0]) if "duration" in g else float("nan")
        for c, _, _ in METRICS:
            v = ok[c].dropna() if c in ok else pd.Series(dtype=float)
            row[c + "_mean"] = float(v.mean()) if len(v) else float("nan")
            row[c + "_sd"] = float(v.std(ddof=1)) if len(v) > 1 else float("nan")
        rows.append(row)
    return starvation.mark_rises(pd.DataFrame(rows))


def _map_page(map_name, stats, refs, seeds, header, causes, fidelity, names):
    lines = [f"# Reference tables: {map_name}", ""] + header + [
        f"Mean ± SD over the seeds of the runs that ended with {USED_STATUS} (n of {seeds} "
        "seeds; **n\\*** marks a cell with fewer seeds than the campaign's; *excl.* counts runs "
        "that ended otherwise, left out; a run that made no visit at all has no idleness: its "
        "cell says so and averages the others). Metric definitions: `docs/metrics.md`. References: "
        "`patrolling_sim.planning.references` (`docs/metrics.md`), at the runs' speed, no goal "
        "wait: the cyclic reference is the idleness of every visit of k robots evenly spaced on "
        "the best closed tour (so it applies to the average, worst and max idleness; a "
        "reference, not a bound: the original's average counts every visit, a route's repeated "
        "passes included), the partition reference the worst idleness of one robot per part of "
        "a balanced partition. *never visited*: in how many seeds some vertex got no visit "
        "in the whole run (and the most such vertices in one run); such a cell's worst "
        "idleness is marked ≥ (a vertex never visited counts the run's length: a lower "
        "bound); ↑ marks a worst idleness over "
        f"{starvation.RISE:g} times that of a smaller team on this map; the notes under a "
        "table give the causes.", "",
        f"![{map_name}]({map_name}.png)", ""]
    for n in sorted(refs):
        r = refs[n]
        s = stats[stats["robots"] == n]
        extra = " vs original |" if fidelity else ""
        lines += [f"## {n} robot{'s' if n > 1 else ''}", "",
                  "| algorithm | n | excl. | " + " | ".join(h for _, h, _ in METRICS)
                  + " | never visited |" + extra,
                  "|---|---|---|" + "---|" * (len(METRICS) + 1 + bool(fidelity))]
        notes = []
        for _, row in s.iterrows():
            mark = "\\*" if row["n"] < seeds else ""
            if row["novisit"]:
                mark += f" ({row['novisit']} without a visit)"
            flag = starvation.flag_text(row["starved"], row["n"], row["starved_most"])
            # a never-visited vertex makes the worst idleness a lower bound (the run's length)
            rise = int(row["rise_from"])
            worst_mark = ("≥ " if flag else "") + ("↑ " if rise else "")
            name = names.get(row["alg"], row["alg"])
            lines.append(f"| {name} | {row['n']}{mark} | {row['excluded']} | " + " | ".join(
                (worst_mark if c == "worst_idleness" else "")
                + _fmt(row[c + "_mean"], row[c + "_sd"], d) for c, _, d in METRICS)
                + f" | {flag} |" + (" " + fidelity_status.cell_text(
                    fidelity, map_name, n, row["alg"], FIDELITY_LINK) + " |" if fidelity else ""))
            cause = starvation.cause_of(causes, row["alg"], map_name, n)
            if flag:
                notes.append(starvation.note_line(
                    row["alg"], row["starved"], row["n"], row["duration"], cause))
            if rise:
                notes.append(starvation.rise_line(row["alg"], row["worst_idleness_mean"], rise,
                                                  row["rise_worst"], cause))
        cy, pa = f"{r.cyclic_idleness:.1f}", f"{r.partition_idleness:.1f}"
        pad = " |" if fidelity else ""
        lines += [f"| *cyclic reference L/(k v)* | | | {cy} | | {cy} | {cy} | | |" + pad,
                  f"| *partition reference* | | | | | {pa} | {pa} | | |" + pad, ""]
        if notes:
            lines += ["Flagged cells:", ""] + notes + [""]
        lines += [
                  f"Best closed tour L = {r.tour_length:.1f} m "
                  f"({'exact' if r.tour_exact else 'heuristic'}); cyclic L/(k v) = "
                  f"{r.cyclic_idleness:.1f} s; partition (slowest part's tour / v, part sizes "
                  f"{r.partition_sizes}) = {r.partition_idleness:.1f} s.", ""]
    return "\n".join(lines)


def build_reference_docs(campaign_dir: str, command: str,
                         now: Optional[datetime.datetime] = None,
                         causes_file: Optional[str] = None, replace: Sequence[str] = (),
                         fidelity_file: Optional[str] = None) -> ReferenceDocs:
    """The pages of ``campaign_dir`` (nothing written). ``command``: the command line that
    generated them, written at the top of the index. ``causes_file``: why some cells have a
    never-visited vertex (:mod:`patrolling_sim.report.starvation`); without it every such
    cell says "cause not documented". ``replace``: campaign folders whose algorithms' runs
    replace those of ``campaign_dir`` (:mod:`patrolling_sim.report.reference_sources`).
    ``fidelity_file``: the fidelity matrix's status file; with it every table gets a column
    "vs original" (:mod:`patrolling_sim.report.fidelity_status`).

    Raises:
        PatrolInputError: one line, for a bad campaign folder, causes or status file.
    """
    causes = starvation.load_causes(causes_file)
    fidelity = fidelity_status.load_status(fidelity_file)
    df, sources = merge_sources(campaign_dir, replace, load_runs)
    prov = sources[0].provenance
    names = display_names(df)
    now = now or datetime.datetime.now(datetime.timezone.utc)
    seeds = int(df.groupby(CELL).size().max())
    stats = _cell_stats(df, seeds)
    docs = ReferenceDocs(total=len(df), done=int((df["status"] == USED_STATUS).sum()),
                         excluded=int(((df["status"] != USED_STATUS)
                                       & (df["status"] != NOT_RUN)).sum()))
    commit = sources[0].commit
    dirty = " (dirty)" if sources[0].dirty else ""
    counts = df["status"].value_counts().sort_index()
    state = (f"**PARTIAL: {docs.done} of {docs.total} runs done** "
             f"({docs.total - docs.done - docs.excluded} not run yet, {docs.excluded} excluded)"
             if docs.partial else f"complete: {docs.done} of {docs.total} runs done"
             + (f", {docs.excluded} excluded" if docs.excluded else ""))
    also = "".join(f"; {', '.join(src.algs)} from the campaign `{src.name}` (code commit "
                   f"`{src.commit[:12]}`{' (dirty)' if src.dirty else ''})"
                   for src in sources[1:])
    header = [f"Generated by `{command}` on {now.strftime('%Y-%m-%d %H:%M UTC')} from the "
              f"campaign `{sources[0].name}` (code commit `{commit[:12]}`{dirty}){also}. "
              f"{state}.", ""]
    speed = float(df["speed"].iloc[0]) if "speed" in df else 1.0
    maps = sorted(df["map"].astype(str).unique())
    algs = sorted(df["alg"].astype(str).unique())
    index = ["# Reference tables", "", "```bash", command, "```", "",
             f"Generated on {now.strftime('%Y-%m-%d %H:%M UTC')}; campaign file "
             f"`{os.path.basename(str(prov.get('file', 'campaign.yaml')))}`, code commit "
             f"`{commit}`{dirty}; campaign run from {prov.get('start', '?')} to "
             f"{prov.get('end', '?')} on `{prov.get('client_host', '?')}`.", "",
             *(["Runs by campaign: every algorithm's runs come from one campaign "
                "(a campaign that re-ran an algorithm replaces its runs):", ""]
               + [f"- {src.line()}" for src in sources] + [""] if len(sources) > 1 else []),
             state + ".", "",
             "Status counts: " + ", ".join(f"{k} {v}" for k, v in counts.items()) + ". Only "
             f"runs that ended with {USED_STATUS} are averaged; the others are counted per "
             "cell (*excl.*). Cells with fewer seeds than the campaign's "
             f"{seeds} are marked n\\*.", "",
             "| map | team sizes | algorithms | runs done | of |", "|---|---|---|---|---|"]
    for m in maps:
        sm = stats[stats["map"] == m]
        sizes = sorted(int(x) for x in sm["robots"].unique())
        tot = int((df["map"] == m).sum())
        index.append(f"| [{m}]({m}.md) | {', '.join(map(str, sizes))} | "
                     f"{sm['alg'].nunique()} | {int(sm['n'].sum())} | {tot} |")
        refs = _map_references(m, sizes, speed)
        docs.files[f"{m}.md"] = _map_page(m, sm, refs, seeds, header, causes, fidelity,
                                          names)
        docs.files[f"{m}.png"] = _figure(m, sm, refs, algs)
    index += starvation.index_section(stats, causes)
    docs.files["README.md"] = "\n".join(index) + "\n"
    return docs


def write_docs(docs: ReferenceDocs, out: str) -> List[str]:
    """Write every page into ``out`` (created); each file replaced atomically."""
    os.makedirs(out, exist_ok=True)
    written = []
    for name, content in sorted(docs.files.items()):
        p = os.path.join(out, name)
        tmp = p + ".part"
        with open(tmp, "wb") as f:
            f.write(content if isinstance(content, bytes) else content.encode())
        os.replace(tmp, p)
        written.append(p)
    return written


def relink_docs(folder: str, fidelity_file: str, now=None) -> List[str]:
    """Relink the column "vs original" of every map page under ``folder`` to
    ``fidelity_file`` and say so in the index
    (:func:`patrolling_sim.report.reference_relink.relinked_files`). Returns the pages
    rewritten; nothing is written if any page fails.

    Raises:
        PatrolInputError: one line, as ``relinked_files``.
    """
    docs = ReferenceDocs(total=0, done=0, excluded=0)
    docs.files = relinked_files(folder, fidelity_file, now)
    return write_docs(docs, folder)


def main(argv=None):

    def _main(args):
        ap = CliParser(prog="reference_docs.py", description=(
            "Write the reference tables (docs/reference/: one page and one figure per map, an "
            "index) from a campaign folder's runs.csv (see docs/campaigns.md)."))
        ap.add_argument("campaign_dir", nargs="?",
                        help="campaign folder (holds runs.csv); not with --relink")
        ap.add_argument("--out", default=os.path.join("docs", "reference"),
                        help="output folder (default: docs/reference)")
        ap.add_argument("--causes", default=None, metavar="FILE",
                        help="YAML file: why cells have a never-visited vertex (the shipped "
                        "tables use campaigns/reference_causes.yaml; see docs/campaigns.md)")
        ap.add_argument("--replace", action="append", default=[], metavar="DIR",
                        help="a campaign folder that re-ran some algorithms over the same "
                        "grid: their runs replace the base campaign's (repeatable)")
        ap.add_argument("--fidelity", default=None, metavar="FILE",
                        help="the fidelity matrix's status CSV (bench/fidelity_matrix.py "
                        "--status): adds a column 'vs original' linked to the matrix")
        ap.add_argument("--relink", default=None, metavar="DIR",
                        help="no campaign: rewrite only the column 'vs original' of the pages "
                        "in DIR from --fidelity FILE (the fidelity matrix grew)")
        a = ap.parse_args(args)
        if a.relink:
            if a.campaign_dir or not a.fidelity:
                ap.error("--relink DIR takes --fidelity FILE and no campaign folder")
            written = relink_docs(a.relink, a.fidelity)
            print(f"reference_docs.py: column 'vs original' relinked in {len(written)} files "
                  f"of {a.relink}")
            return 0
        if not a.campaign_dir:
            ap.error("the following arguments are required: campaign_dir")
        command = shlex.join(["scripts/reference_docs.py"] + list(args))
        docs = build_reference_docs(a.campaign_dir, command, causes_file=a.causes,
                                    replace=a.replace, fidelity_file=a.fidelity)
        write_docs(docs, a.out)
        print(f"reference_docs.py: {len(docs.files)} files in {a.out} ({docs.done} of "
              f"{docs.total} runs done{', PARTIAL' if docs.partial else ''})")
        return 0
    return run_main(_main, "reference_docs.py", sys.argv[1:] if argv is None else argv)
