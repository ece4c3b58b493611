"""Graph extraction, steps 2-4: the skeleton of the usable space as a pixel graph, split into
branches between junctions and end points, spur pruning and the grouping of close junctions
(docs/graph_extraction.md). Ties are broken by pixel order, so the result is deterministic.
"""
import math

import networkx as nx
import numpy as np


def pixel_graph(skel):
    """networkx Graph of skeleton pixels (row, col), 8-connected, weights 1 or sqrt(2).
    Diagonal links that duplicate a 4-connected detour are left out (no tiny triangles)."""
    G = nx.Graph()
    pts = list(zip(*np.nonzero(skel)))
    G.add_nodes_from(pts)
    s = set(pts)
    for r, c in pts:
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
            q = (r + dr, c + dc)
            if q not in s:
                continue
            if dr and dc and ((r + dr, c) in s or (r, c + dc) in s):
                continue
            G.add_edge((r, c), q, weight=math.hypot(dr, dc))
    return G


def split_branches(P):
    """Split a pixel graph into branches: chains of degree-2 pixels between 'node' pixels
    (degree != 2). Returns (nodes, branches); each branch is a list of pixels from one node to
    another (both included). A pure cycle gets its lowest pixel as a node."""
    nodes = sorted(p for p in P.nodes if P.degree(p) != 2)
    for comp in nx.connected_components(P):
        if not any(P.degree(p) != 2 for p in comp):
            nodes.append(min(comp))
    nodes = sorted(set(nodes))
    node_set = set(nodes)
    seen_edges = set()
    branches = []
    for a in nodes:
        for b in sorted(P.neighbors(a)):
            if (a, b) in seen_edges:
                continue
            path = [a, b]
            seen_edges.add((a, b))
            seen_edges.add((b, a))
            prev, cur = a, b
            while cur not in node_set:
                nxt = [q for q in sorted(P.neighbors(cur)) if q != prev]
                if not nxt:
                    break
                prev, cur = cur, nxt[0]
                seen_edges.add((prev, cur))
                seen_edges.add((cur, prev))
                path.append(cur)
            branches.append(path)
    return nodes, branches


def path_length(path):
    return sum(math.hypot(a[0] - b[0], a[1] - b[1]) for a, b in zip(path, path[1:]))


def prune(skel, clearance_px, min_dead_end_px):
    """Remove dead-end branches reaching less than ``min_dead_end_px`` beyond the free disc
    of their junction (one pass; see the module docstring)."""
    P = pixel_graph(skel)
    nodes, branches = split_branches(P)
    deg = dict(P.degree())
    out = skel.copy()
    if len(branches) <= 1:
        return out
    for br in branches:
        a, b = br[0], br[-1]
        ends = [p for p in (a, b) if deg[p] == 1]
        if len(ends) != 1:
            continue
        junction = b if ends[0] == a else a
        if deg[junction] < 3:
            continue
        if path_length(br) - clearance_px[junction] < min_dead_end_px:
            for p in br:
                if p != junction:
                    out[p] = False
    # removing a spur can leave a junction pixel with a 1-pixel stub: skeletonize again
    from skimage.morphology import skeletonize
    return skeletonize(out)


def merge_close_nodes(P, nodes, branches, merge_px):
    """Group nodes joined by a branch shorter than ``merge_px`` (and adjacent node pixels):
    each group becomes one vertex."""
    U = nx.Graph()
    U.add_nodes_from(nodes)
    for br in branches:
        if br[0] != br[-1] and path_length(br) < merge_px and P.degree(br[0]) != 1 \
                and P.degree(br[-1]) != 1:
            U.add_edge(br[0], br[-1])
    groups = [sorted(g) for g in nx.connected_components(U)]
    groups.sort()
    return groups
