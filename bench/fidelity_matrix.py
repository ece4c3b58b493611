#!/usr/bin/python3
"""The fidelity matrix (docs/fidelity_matrix.md): for every cell (map x team size x
algorithm) with stored runs of the original's own agents (tests/unit/data/original_matrix/,
README there), the mean of those runs against this project's graph mode in the same world
(the same map, team, default start positions and duration; straight-line travel at 1 m/s, no
interference, goal wait 0, the agents' clock started ``GO_TIME`` s before GO) over several
seeds, and against this project's agents in ROS mode (the abstract world) where the runs file
holds runs of ours for the cell.

Figures: average idleness (mean of the idleness samples), maximum idleness, visits; each
compared with the original's mean within the tolerances of tests/unit/original_matrix.py
(avg 10 %, max 25 %, visits 10 %). A cell listed in the known-differences file is marked so.

Usage:
    bench/fidelity_matrix.py [--runs CSV] [--seeds 2] [--out docs/fidelity_matrix.md]
                             [--json FILE] [--status FILE]

--status writes one CSV row per cell (map, robots, alg, status within / known / differs,
detail), which scripts/reference_docs.py --fidelity links from the reference tables.
"""
import argparse
import json
import os
import statistics
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "unit"))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
sys.path.insert(0, os.path.join(ROOT, "src", "spqrel_nav_lite", "src"))
import original_matrix as om  # noqa: E402
from patrolling_sim.report import fidelity_status  # noqa: E402

MARK = {True: "yes", False: "**no**"}


def fmt(fig):
    return f"{fig[0]:.1f} / {fig[1]:.1f} / {fig[2]:.0f}"


def fmt_rel(cmp):
    return " / ".join(f"{cmp[m][0]:+.0%}" for m in om.METRICS)


def verdict(cmp, reasons):
    """'yes', '**no**' (metrics out of tolerance named), or 'known' where every metric out
    of tolerance is a documented difference."""
    bad = [m for m in om.METRICS if not cmp[m][1]]
    if not bad:
        return "yes", True
    if all(reasons.get(m) for m in bad):
        return "known (" + ", ".join(bad) + ")", False
    return "**no** (" + ", ".join(bad) + ")", False


def measure(rows, seeds):
    """[(key, original runs, graph runs, ROS runs, original runs left out)] for every cell of
    the original, in the order algorithm, map, team size."""
    ros = {}
    for who in ("ours_separate", "ours_shared"):
        for k, v in om.cells(rows, who).items():
            ros.setdefault(k, []).extend(v)
    crashes = om.crashes(rows)
    out = []

    def order(item):
        (map_name, robots, alg, duration), _ = item
        return alg, map_name.lower(), robots, duration

    for key, orig in sorted(om.cells(rows).items(), key=order):
        map_name, robots, alg, duration = key
        graph = [om.graph_run(map_name, robots, alg, s, duration)[:3] for s in range(seeds)]
        out.append((key, orig, graph, ros.get(key, []), crashes.get(key, 0)))
        print(f"  {map_name} {robots} {alg}: done", file=sys.stderr, flush=True)
    return out


HEADER = ("| map | N | original: runs, avg / max / visits | original's max: range "
          "| graph mode, {seeds} seeds | graph vs original (avg / max / visits) | within "
          "| ROS mode (runs) | ROS vs original |")


def assess(cells, known):
    """[(cell, verdict word, within, status word, relative differences text, score)]:
    every cell's comparison; score is the largest difference in units of its tolerance."""
    out = []
    for cell in cells:
        (map_name, robots, alg, _), orig, graph = cell[:3]
        cmp = om.compare(om.mean_figures(orig), om.mean_figures(graph))
        reasons = {m: om.known_reason(known, map_name, robots, alg, m) for m in om.METRICS}
        word, ok = verdict(cmp, reasons)
        status = "within" if ok else "known" if word.startswith("known") else "differs"
        score = max(abs(cmp[m][0]) / om.TOL[m] for m in om.METRICS)
        out.append((cell, word, ok, status, fmt_rel(cmp), score))
    return out


def summary_table(assessed):
    """Algorithms x maps: cells within tolerance / cells measured (+ known differences)."""
    maps = sorted({a[0][0][0] for a in assessed}, key=str.lower)
    algs = sorted({a[0][0][2] for a in assessed})
    count = {}
    for (key, *_), _, ok, status, _, _ in assessed:
        c = count.setdefault((key[2], key[0]), [0, 0, 0])
        c[0] += 1
        c[1] += ok
        c[2] += status == "known"
    lines = ["| algorithm | " + " | ".join(maps) + " | all |",
             "|---|" + "---|" * (len(maps) + 1)]
    for alg in algs:
        row, tot = [], [0, 0, 0]
        for m in maps:
            c = count.get((alg, m))
            if not c:
                row.append("")
                continue
            tot = [t + x for t, x in zip(tot, c)]
            row.append(f"{c[1]}/{c[0]}" + (f" (+{c[2]} known)" if c[2] else ""))
        all_txt = f"{tot[1]}/{tot[0]}" + (f" (+{tot[2]} known)" if tot[2] else "")
        lines.append(f"| [{alg}](#{alg.lower()}) | " + " | ".join(row) + f" | {all_txt} |")
    return lines


def cell_tables(assessed, seeds):
    """One section per algorithm, a row per cell."""
    lines, current = [], None
    for ((map_name, robots, alg, _), orig, graph, ros, crashed), word, _, _, rel, _ in assessed:
        if alg != current:
            current = alg
            lines += ["", f"### {alg}", "", HEADER.format(seeds=seeds),
                      "|---|---|---|---|---|---|---|---|---|"]
        ref, got = om.mean_figures(orig), om.mean_figures(graph)
        ros_txt = ros_cmp = ""
        if ros:
            r = om.mean_figures(ros)
            ros_txt = f"{fmt(r)} ({len(ros)})"
            ros_cmp = fmt_rel(om.compare(ref, r))
        spread = f"{min(r[1] for r in orig):.0f}-{max(r[1] for r in orig):.0f}"
        runs = f"{len(orig)}" + (f" (+{crashed} left out)" if crashed else "")
        lines.append(f"| {map_name} | {robots} | {runs}: {fmt(ref)} | {spread} "
                     f"| {fmt(got)} | {rel} | {word} | {ros_txt} | {ros_cmp} |")
    return lines


def page(cells, known, seeds, runs_path):
    assessed = assess(cells, known)
    n_cells = len(assessed)
    n_in = sum(a[2] for a in assessed)
    n_known = sum(a[3] == "known" for a in assessed)
    status = [(k[0], k[1], k[2], st, rel) for (k, *_), _, _, st, rel, _ in assessed]
    worst = sorted(((a[5], f"{a[0][0][0]} {a[0][0][1]} {a[0][0][2]}", a[4]) for a in assessed),
                   reverse=True)
    durations = sorted({k[3] for k, *_ in cells})
    rel = os.path.relpath(runs_path, ROOT)
    out = [
        "# Fidelity matrix: the original's own agents against this project",
        "",
        "Generated; regenerate with",
        "",
        "```",
        f"bench/fidelity_matrix.py --runs {rel} --seeds {seeds} --out docs/fidelity_matrix.md \\",
        "    --status docs/fidelity_status.csv",
        "```",
        "",
        "Every row is one cell (map, team size N, algorithm) with runs of the original's own "
        "agents (built from its source, run in this project's abstract world with this "
        "project's monitor; how, in the README beside the runs file) against this project's "
        "graph mode in the same world: the same map, team and default start positions, "
        f"{' and '.join(f'{d:g}' for d in durations)} sim s after GO, straight-line travel "
        "at 1 m/s, no interference and no teammate positions heard (the world sends no "
        f"move_base feedback), goal wait 0, the agents' clock started {om.GO_TIME:g} s "
        "before GO (docs/fidelity.md, \"The clock at GO\"), seeds 0 to "
        f"{seeds - 1}. Figures: average idleness (s, mean of the idleness samples) / maximum "
        "idleness (s) / visits, means over the runs; differences relative to the original's "
        f"mean. Within tolerance: average {om.TOL['avg']:.0%}, maximum "
        f"{om.TOL['max']:.0%}, visits {om.TOL['visits']:.0%}; \"known\" marks a difference "
        "documented in the known-differences file beside the runs (its reason is below). "
        "The ROS-mode column holds runs of our agents in the abstract world where they exist. "
        "\"+n left out\": runs of the original in which an agent's process ended before the "
        "run did (the original's CBLS agent crashes now and then), not averaged. The "
        "original's RAND agent reseeds its generator from the wall clock before every draw, "
        "so its figures depend on the pace it ran at ([fidelity_draws.md]"
        "(fidelity_draws.md)); graph mode draws from seeded generators.",
        "",
        f"**{n_in} of {n_cells} cells within tolerance**; {n_known} more differ only in "
        "documented ways (known differences), "
        f"{n_cells - n_in - n_known} in undocumented ways.",
        "",
        "## Summary: cells within tolerance / cells measured",
        "",
        *summary_table(assessed),
        "",
        "## Largest differences (in units of the tolerance)",
        "",
    ]
    out += [f"- {name}: {rel_txt}" for score, name, rel_txt in worst[:8] if score > 1]
    out += ["", "## Cells"]
    out += cell_tables(assessed, seeds)
    if known:
        out += ["", "## Known differences", ""]
        out += [f"- **{k[0]} {k[1]} {k[2]}** (metric {k[3]}): {v}" for k, v in known.items()]
    return "\n".join(out) + "\n", n_in, n_cells, status


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default=om.RUNS, help="summary CSV of the original's runs")
    ap.add_argument("--seeds", type=int, default=len(om.SEEDS))
    ap.add_argument("--out", help="write the Markdown page here (default: print it)")
    ap.add_argument("--json", help="write every cell's figures here")
    ap.add_argument("--status", help="write every cell's status here (CSV, for "
                    "scripts/reference_docs.py --fidelity)")
    a = ap.parse_args()
    rows = om.read_rows(a.runs)
    cells = measure(rows, a.seeds)
    text, n_in, n_cells, status = page(cells, om.known_differences(), a.seeds,
                                       os.path.abspath(a.runs))
    if a.out:
        with open(a.out, "w", encoding="utf-8") as f:
            f.write(text)
        print(f"{a.out}: {n_in} of {n_cells} cells within tolerance")
    else:
        print(text)
    if a.status:
        fidelity_status.write_status(a.status, status)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump([{"cell": list(k), "original": o, "graph": g, "ros": r,
                        "left_out": d,
                        "original_sd": [statistics.pstdev(x[i] for x in o) for i in range(3)]}
                       for k, o, g, r, d in cells], f)


if __name__ == "__main__":
    main()
