"""Precomputed shortest-path tables of a patrol graph, through networkx
(docs/architecture.md, "graph").

:class:`patrolling_sim.model.graph.PatrolGraph` builds these once per graph, lazily: all-pairs
shortest-path costs and hop counts (``networkx.floyd_warshall_numpy``: vectorised with
numpy, a few ms on the largest shipped graph, and no scipy import -- scipy.sparse.csgraph
costs 0.03 CPU s to import, more than the whole table on the shipped maps), and the next hop
of a shortest path from every vertex to every other (so a path is a walk through a table,
no search in the hot loop).

Tie rule (explicit, so that paths do not depend on a library's internal order): of several
shortest paths from ``s`` to ``t``, the one whose last edge ``u -> t`` has the smallest
``(dist[s, u], u)`` -- the predecessor that a Dijkstra search ordered by (cost, vertex id)
settles first -- applied recursively back to ``s``. These are exactly the paths of the
project's earlier hand-written Dijkstra, on which the fidelity tests rely. On a graph with a
zero-cost edge, costs are first compared and then the number of edges (weights
``cost * n + 1``), so that every walk through the next-hop table ends.
"""
import numpy as np
import networkx as nx


def _floyd_warshall(n, arcs, weighted=True):
    """(n, n) all-pairs shortest costs (inf: unreachable) of the arcs ``{(u, w): cost}``;
    unweighted: hop counts."""
    D = nx.DiGraph()
    D.add_nodes_from(range(n))
    D.add_weighted_edges_from((u, w, c) for (u, w), c in arcs.items())
    return nx.floyd_warshall_numpy(D, nodelist=range(n), weight="weight" if weighted else None)


def _tight_predecessors(dist, arcs):
    """(n, n) predecessor table by the module's tie rule (-1: none)."""
    n = dist.shape[0]
    pred = np.full((n, n), -1, dtype=np.int64)
    if not arcs:
        return pred
    uw = np.array(sorted(arcs), dtype=np.int64)
    U, W = uw[:, 0], uw[:, 1]
    C = np.array([arcs[(u, w)] for u, w in uw.tolist()], dtype=float)
    for s in range(n):
        du = dist[s, U]
        tight = np.isfinite(du) & (du + C == dist[s, W]) & (W != s)
        if not tight.any():
            continue
        u, w, d = U[tight], W[tight], du[tight]
        order = np.lexsort((u, d, w))          # by target, then (dist[s, u], u)
        w_sorted = w[order]
        first = np.ones(len(order), dtype=bool)
        first[1:] = w_sorted[1:] != w_sorted[:-1]
        pred[s, w_sorted[first]] = u[order][first]
    return pred


def _next_hops(pred):
    """(n, n) table: the first vertex after ``s`` on the path to ``t`` (-1: none)."""
    n = pred.shape[0]
    rows = np.arange(n)[:, None]
    cur = np.tile(np.arange(n), (n, 1))
    valid = pred >= 0
    active = valid & (pred != rows)
    while active.any():
        cur = np.where(active, pred[rows, cur], cur)
        active &= pred[rows, cur] != rows
    return np.where(valid, cur, -1)


def shortest_path_tables(n, arcs):
    """(dist, next_hop) for the directed arcs ``{(u, w): cheapest cost}`` of ``n``
    vertices: ``dist`` (n, n) float (inf: unreachable), ``next_hop`` (n, n) int (-1: none)."""
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 0), dtype=np.int64)
    if any(c == 0 for c in arcs.values()):
        # ties by fewest edges: every weight > 0; cost = weight // n (edges < n)
        arcs = {uw: c * n + 1 for uw, c in arcs.items()}
        lex = _floyd_warshall(n, arcs)
        return np.floor(lex / n), _next_hops(_tight_predecessors(lex, arcs))
    dist = _floyd_warshall(n, arcs)
    return dist, _next_hops(_tight_predecessors(dist, arcs))


def hop_table(n, arcs):
    """(n, n) float array of hop counts (edges on a fewest-edge path; inf: unreachable)."""
    if n == 0:
        return np.zeros((0, 0))
    return _floyd_warshall(n, arcs, weighted=False)
