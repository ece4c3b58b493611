"""Graph extraction, clean-up of the vertex graph (docs/graph_extraction.md, step 4): merge
the ends of very short edges, drop stub dead ends, number the vertices top-left first.
"""
import math

import networkx as nx


def contract_short(vert_px, edges, min_px, clear_px):
    """Merge the two ends of every edge shorter than ``min_px`` (straight line); the merged
    vertex is the one with the larger clearance. Returns renumbered (vert_px, edges)."""
    parent = list(range(len(vert_px)))

    def find(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v
    for u, w, _ in sorted(edges):
        a, b = find(u), find(w)
        if a != b and math.hypot(vert_px[a][0] - vert_px[b][0],
                                 vert_px[a][1] - vert_px[b][1]) < min_px:
            keep, drop = (a, b) if (clear_px[vert_px[a]], -a) >= (clear_px[vert_px[b]], -b) \
                else (b, a)
            parent[drop] = keep
    roots = sorted({find(v) for v in range(len(vert_px))})
    new_id = {r: i for i, r in enumerate(roots)}
    out_edges = {}
    for u, w, a in edges:
        x, y = new_id[find(u)], new_id[find(w)]
        if x != y:
            out_edges.setdefault((min(x, y), max(x, y)), a)
    return [vert_px[r] for r in roots], [(x, y, a) for (x, y), a in sorted(out_edges.items())]


def drop_stub_ends(vert_px, edges, min_px):
    """Drop dead-end vertices closer than ``min_px`` to their only neighbour (the leftovers
    of tiny skeleton spurs next to a junction), repeatedly; renumber the rest."""
    keep = set(range(len(vert_px)))
    nbrs = {v: set() for v in keep}
    for u, w, _ in edges:
        nbrs[u].add(w)
        nbrs[w].add(u)
    changed = True
    while changed and len(keep) > 2:
        changed = False
        for v in sorted(keep):
            live = nbrs[v] & keep
            if len(live) == 1:
                w = next(iter(live))
                if math.hypot(vert_px[v][0] - vert_px[w][0], vert_px[v][1] - vert_px[w][1]) \
                        < min_px:
                    keep.discard(v)
                    changed = True
                    if len(keep) <= 2:
                        break
    new_id = {v: i for i, v in enumerate(sorted(keep))}
    return ([vert_px[v] for v in sorted(keep)],
            [(min(new_id[u], new_id[w]), max(new_id[u], new_id[w]), a)
             for u, w, a in edges if u in keep and w in keep])


def renumber(G, edge_paths):
    """Number vertices top-left first (rows from the top, then columns), as a person reading
    the picture would; returns (graph, edge_paths) renumbered."""
    order = sorted(G.nodes, key=lambda v: (-G.nodes[v]["y_px"], G.nodes[v]["x_px"], v))
    new = {old: i for i, old in enumerate(order)}
    H = nx.MultiDiGraph(**G.graph)
    for old in order:
        H.add_node(new[old], **G.nodes[old])
    for old in order:
        outs = sorted(((new[w], d) for _, w, d in G.out_edges(old, data=True)),
                      key=lambda t: t[0])
        for w, d in outs:
            H.add_edge(new[old], w, **d)
    paths_ = {(new[u], new[w]): pth for (u, w), pth in edge_paths.items()}
    return H, paths_
