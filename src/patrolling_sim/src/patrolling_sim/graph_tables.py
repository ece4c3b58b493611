"""Precomputed shortest-path tables of a patrol graph, through ``scipy.sparse.csgraph``
(docs/architecture.md, "graph").

:class:`patrolling_sim.graph.PatrolGraph` builds these once per graph, lazily: all-pairs
shortest-path costs (csgraph Dijkstra), the next hop of a shortest path from every vertex
to every other (so a path is a walk through a table, no search in the hot loop) and hop
counts (csgraph, unweighted).

Tie rule (explicit, so that paths do not depend on a library's heap order): of several
shortest paths from ``s`` to ``t``, the one whose last edge ``u -> t`` has the smallest
``(dist[s, u], u)`` -- the predecessor that a Dijkstra search ordered by (cost, vertex id)
settles first -- applied recursively back to ``s``. These are exactly the paths of the
project's earlier hand-written Dijkstra, on which the fidelity tests rely. On a graph with
a zero-cost edge that rule is not well founded (equal-cost cycles); there the predecessors
of csgraph's own search are used.
"""
import numpy as np


def _matrix(n, arcs, weighted=True):
    """Sparse (n, n) matrix of the arcs ``{(u, w): cost}``; zero costs stay edges."""
    from scipy.sparse import csr_matrix
    if not arcs:
        return csr_matrix((n, n))
    uw = np.array(list(arcs.keys()), dtype=np.int64)
    data = np.array(list(arcs.values()), dtype=float) if weighted else np.ones(len(uw))
    m = csr_matrix((data, (uw[:, 0], uw[:, 1])), shape=(n, n))
    return m


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
    vertices: ``dist`` (n, n) float (inf: unreachable), ``next_hop`` (n, n) int."""
    from scipy.sparse.csgraph import dijkstra
    if n == 0:
        return np.zeros((0, 0)), np.zeros((0, 0), dtype=np.int64)
    zero = any(c == 0 for c in arcs.values())
    if zero:
        # explicit zeros in a sparse matrix are edges for csgraph; kept by csr_matrix
        dist, pred = dijkstra(_matrix(n, arcs), directed=True, return_predecessors=True)
        pred = np.where(pred < 0, -1, pred).astype(np.int64)
    else:
        dist = dijkstra(_matrix(n, arcs), directed=True)
        pred = _tight_predecessors(dist, arcs)
    return dist, _next_hops(pred)


def hop_table(n, arcs):
    """(n, n) float array of hop counts (edges on a fewest-edge path; inf: unreachable)."""
    from scipy.sparse.csgraph import shortest_path
    if n == 0:
        return np.zeros((0, 0))
    return shortest_path(_matrix(n, arcs, weighted=False), method="D", directed=True,
                         unweighted=True)
