#!/usr/bin/python3
"""Graph-extraction benchmark: for every shipped map, extract a patrol graph with the default
options and compare it with the hand-made one (vertex counts, coverage at 5 m with line of
sight, acceptance checks, extraction time). Prints a Markdown table (and writes it to --out);
with --pictures DIR also saves each extracted graph's picture there.

Usage:
    bench/extract_bench.py [--maps ...] [--out FILE] [--pictures DIR]
"""
import argparse
import datetime
import logging
import os
import platform
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    sys.path.insert(0, os.path.join(ROOT, "src", _pkg, "src"))

from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.extraction.coverage import check_graph, coverage  # noqa: E402
from patrolling_sim.model.draw import draw_graph, save_png  # noqa: E402
from patrolling_sim.extraction.extract import ExtractionParams, extract_graph  # noqa: E402
from patrolling_sim.model.graph import PatrolGraph, load_graph, undirected_edge_count  # noqa: E402
from spqrel_nav_lite.mapio import load_map  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--maps", nargs="*")
    ap.add_argument("--out")
    ap.add_argument("--pictures")
    a = ap.parse_args()
    logging.disable(logging.WARNING)
    rows = ["| map | V hand-made | V extracted | E extracted | coverage hand-made | "
            "coverage extracted | checks failed (extracted) | extraction s |",
            "|---|---|---|---|---|---|---|---|"]
    for m in a.maps or paths.available_maps():
        yaml_path, graph_path = paths.map_files(m)
        occ = load_map(yaml_path)
        hand = load_graph(graph_path, warn=False)
        t0 = time.process_time()
        res = extract_graph(occ, name=m)
        dt = time.process_time() - t0
        G = res.graph
        problems = check_graph(occ, G, path_clearance=ExtractionParams().clearance)
        ch, co = coverage(occ, PatrolGraph(hand)), coverage(occ, PatrolGraph(G))
        row = (f"| {m} | {hand.number_of_nodes()} | {G.number_of_nodes()} | "
               f"{undirected_edge_count(G)} | {100 * ch:.1f} % | {100 * co:.1f} % | "
               f"{len(problems)} | {dt:.1f} |")
        print(row, flush=True)
        rows.append(row)
        if a.pictures:
            os.makedirs(a.pictures, exist_ok=True)
            save_png(draw_graph(occ, PatrolGraph(G)),
                     os.path.join(a.pictures, f"{m}-extracted.png"))
    head = (f"Graph extraction, default options ({platform.node()}, {datetime.date.today()}; "
            f"bench/extract_bench.py; extraction time = CPU seconds)\n\n")
    if a.out:
        with open(a.out, "w", encoding="utf-8") as f:
            f.write(head + "\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
