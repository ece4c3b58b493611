"""Patrol graphs: the ``.graph`` file format of patrolling_sim, as a networkx graph.

File format (whitespace separated tokens, blank lines irrelevant)::

    V  width_px  height_px  resolution  offset_x  offset_y
    id x_px y_px k   (neighbour_id direction cost_px) * k      -- V records, ids 0..V-1

Coordinates convert to metres in the map frame with ``x = x_px*res + offset_x`` and
``y = y_px*res + offset_y`` (no y flip: pixel y already counts upward). Edge costs are
integer pixel lengths; every algorithm uses them, motion uses metres.

:func:`load_graph` returns a :class:`networkx.MultiDiGraph`:

- graph attributes: ``name``, ``path``, ``width_px``, ``height_px``, ``resolution``,
  ``offset_x``, ``offset_y``;
- node attributes: ``x_px``, ``y_px``, ``pos`` (metres, tuple);
- one directed edge per neighbour entry with ``direction``, ``cost_px``, ``cost_m`` and
  ``slot`` (its position in the vertex's record). Edges are normally listed at both ends;
  multi-edges are kept. networkx groups a vertex's edges by neighbour, so a vertex that
  lists the same neighbour twice with another in between comes back from ``out_edges`` in
  another order than the file's: :func:`out_edges_in_order` gives the file's order (the
  original's agents walk the neighbour lists in that order).

:class:`PatrolGraph` wraps such a graph with the lookup tables the algorithms need
(ordered neighbour lists, all-pairs shortest path costs, hop counts; the tables and their
tie rule are in :mod:`patrolling_sim.model.tables`).
"""
import logging
import math
import os

import networkx as nx
import numpy as np

from patrolling_sim.common.errors import GraphFormatError
from patrolling_sim.common.textfile import write_atomic
from patrolling_sim.model.tables import hop_table, shortest_path_tables

log = logging.getLogger(__name__)

DIRECTIONS = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


class _Tokens:
    """Token stream with line numbers, for error messages that point at the file line."""

    def __init__(self, path, text):
        self.path = path
        self.items = []
        for lineno, line in enumerate(text.splitlines(), 1):
            for tok in line.split():
                self.items.append((tok, lineno))
        self.i = 0
        self.last_line = len(text.splitlines())

    def _next(self, what):
        if self.i >= len(self.items):
            raise GraphFormatError(
                f"{self.path}:{self.last_line}: file is truncated: expected {what}")
        tok, line = self.items[self.i]
        self.i += 1
        return tok, line

    def int(self, what, minimum=None):
        tok, line = self._next(what)
        try:
            value = int(tok)
        except ValueError:
            raise GraphFormatError(
                f"{self.path}:{line}: {what} must be an integer, got '{tok}'") from None
        if minimum is not None and value < minimum:
            raise GraphFormatError(
                f"{self.path}:{line}: {what} must be >= {minimum}, got {value}")
        return value, line

    def float(self, what, positive=False):
        tok, line = self._next(what)
        try:
            value = float(tok)
        except ValueError:
            raise GraphFormatError(
                f"{self.path}:{line}: {what} must be a number, got '{tok}'") from None
        if not math.isfinite(value) or (positive and value <= 0):
            raise GraphFormatError(
                f"{self.path}:{line}: {what} must be a {'positive ' if positive else ''}"
                f"finite number, got '{tok}'")
        return value, line

    def word(self, what):
        return self._next(what)

    def rest(self):
        return self.items[self.i:]


def parse_graph(text, path="<string>"):
    """Parse ``.graph`` text into a MultiDiGraph (see module docstring).

    Raises:
        GraphFormatError: one line naming ``path:line`` and the problem (truncated file,
            non-numeric token, wrong vertex count or id, neighbour id out of range,
            unknown direction, negative cost, trailing data).
    """
    tk = _Tokens(path, text)
    n, _ = tk.int("vertex count", minimum=1)
    width, _ = tk.int("image width (px)", minimum=1)
    height, _ = tk.int("image height (px)", minimum=1)
    res, _ = tk.float("resolution (m/px)", positive=True)
    ox, _ = tk.float("offset_x (m)")
    oy, _ = tk.float("offset_y (m)")
    G = nx.MultiDiGraph(name=os.path.splitext(os.path.basename(path))[0], path=path,
                        width_px=width, height_px=height, resolution=res,
                        offset_x=ox, offset_y=oy)
    pending = []
    for expected in range(n):
        vid, line = tk.int(f"id of vertex record {expected} (of {n})")
        if vid != expected:
            raise GraphFormatError(
                f"{path}:{line}: vertex record {expected} has id {vid}; ids must be "
                f"0..{n - 1} in order (is the vertex count {n} right?)")
        x, _ = tk.int(f"x (px) of vertex {vid}")
        y, _ = tk.int(f"y (px) of vertex {vid}")
        k, _ = tk.int(f"neighbour count of vertex {vid}", minimum=0)
        G.add_node(vid, x_px=x, y_px=y, pos=(x * res + ox, y * res + oy))
        for j in range(k):
            w, wline = tk.int(f"neighbour {j + 1}/{k} id of vertex {vid}")
            if not 0 <= w < n:
                raise GraphFormatError(
                    f"{path}:{wline}: neighbour id {w} of vertex {vid} is out of range "
                    f"0..{n - 1}")
            if w == vid:
                raise GraphFormatError(f"{path}:{wline}: vertex {vid} lists itself as neighbour")
            d, dline = tk.word(f"direction of edge {vid}->{w}")
            if d not in DIRECTIONS:
                raise GraphFormatError(
                    f"{path}:{dline}: direction of edge {vid}->{w} must be one of "
                    f"{'/'.join(DIRECTIONS)}, got '{d}'")
            c, _ = tk.int(f"cost (px) of edge {vid}->{w}", minimum=0)
            pending.append((vid, w, d, c, j))
    rest = tk.rest()
    if rest:
        tok, line = rest[0]
        raise GraphFormatError(
            f"{path}:{line}: unexpected data '{tok}' after the {n} vertex records "
            f"(is the vertex count or a neighbour count wrong?)")
    for u, w, d, c, j in pending:
        G.add_edge(u, w, direction=d, cost_px=c, cost_m=c * res, slot=j)
    return G


def out_edges_in_order(G, v):
    """The out-edges ``(v, w, data)`` of ``v`` in the order of its record in the graph
    file (their ``slot``); edges without a ``slot`` (added by code, not read from a file)
    follow those with one, in the order they were added."""
    edges = list(G.out_edges(v, data=True))
    return sorted(edges, key=lambda e: e[2].get("slot", math.inf))


def load_graph(path, occupancy=None, warn=True):
    """Read a ``.graph`` file.

    Args:
        path: file path.
        occupancy: optional :class:`spqrel_nav_lite.mapio.OccupancyMap`; vertices on
            occupied or unknown cells, or outside it, produce warnings.
        warn: log the warnings found by :func:`graph_warnings`.

    Returns:
        networkx.MultiDiGraph (see module docstring).

    Raises:
        GraphFormatError: missing/unreadable file or malformed content (one line).
    """
    try:
        with open(path, encoding="utf-8", errors="strict") as f:
            text = f.read()
    except FileNotFoundError:
        raise GraphFormatError(f"{path}: graph file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise GraphFormatError(f"{path}: cannot read graph file ({e.__class__.__name__})") from None
    G = parse_graph(text, path)
    if warn:
        for w in graph_warnings(G, occupancy):
            log.warning("%s", w)
    return G


def graph_warnings(G, occupancy=None):
    """Return non-fatal problems: asymmetric or one-sided edges, disconnection, vertices
    on non-free map cells. Each item is one line naming the file."""
    path = G.graph.get("path", "<graph>")
    out = []
    costs = {}
    for u, w, d in G.edges(data=True):
        costs.setdefault((u, w), []).append(d["cost_px"])
    for (u, w), cs in sorted(costs.items()):
        if u > w:
            continue
        back = costs.get((w, u))
        if back is None:
            out.append(f"{path}: edge {u}->{w} is not listed at vertex {w} (one-sided edge)")
        elif sorted(cs) != sorted(back):
            out.append(f"{path}: asymmetric edge cost {u}->{w} = {cs} but {w}->{u} = {back}")
    for (u, w) in sorted(costs):
        if u > w and (w, u) not in costs:
            out.append(f"{path}: edge {u}->{w} is not listed at vertex {w} (one-sided edge)")
    if G.number_of_nodes() > 1 and not nx.is_weakly_connected(G):
        comps = nx.number_weakly_connected_components(G)
        out.append(f"{path}: graph is disconnected ({comps} components)")
    if occupancy is not None:
        for v, d in G.nodes(data=True):
            x, y = d["pos"]
            state = occupancy.cell_state(x, y)
            if state != "free":
                out.append(f"{path}: vertex {v} at ({x:.3f}, {y:.3f}) m lies on "
                           f"{state} map cell")
    return out


def _fmt_float(x):
    return repr(float(x))


def format_graph(G):
    """Serialise a graph produced by :func:`parse_graph` back to ``.graph`` text.

    The layout is the one of the shipped files: one token per line, a blank line after
    the header and after each vertex record. ``parse_graph(format_graph(G))`` equals G.
    """
    a = G.graph
    lines = [str(G.number_of_nodes()), str(a["width_px"]), str(a["height_px"]),
             _fmt_float(a["resolution"]), _fmt_float(a["offset_x"]), _fmt_float(a["offset_y"]), ""]
    for v in range(G.number_of_nodes()):
        d = G.nodes[v]
        edges = out_edges_in_order(G, v)
        lines += [str(v), str(d["x_px"]), str(d["y_px"]), str(len(edges))]
        for _, w, e in edges:
            lines += [str(w), e["direction"], str(e["cost_px"])]
        lines.append("")
    return "\n".join(lines) + "\n"


def write_graph(G, path):
    """Write ``G`` to ``path`` atomically (a temporary file renamed into place)."""
    write_atomic(path, format_graph(G))


def graphs_equal(G1, G2):
    """True if two patrol graphs have the same header, vertices and ordered edge lists."""
    keys = ("width_px", "height_px", "resolution", "offset_x", "offset_y")
    if any(G1.graph[k] != G2.graph[k] for k in keys):
        return False
    if G1.number_of_nodes() != G2.number_of_nodes():
        return False
    for v in G1.nodes:
        if G1.nodes[v] != G2.nodes[v]:
            return False
        e1 = [(w, d["direction"], d["cost_px"]) for _, w, d in out_edges_in_order(G1, v)]
        e2 = [(w, d["direction"], d["cost_px"]) for _, w, d in out_edges_in_order(G2, v)]
        if e1 != e2:
            return False
    return True


def undirected_edge_count(G):
    """Number of distinct undirected vertex pairs joined by an edge."""
    return len({(min(u, w), max(u, w)) for u, w in G.edges()})


def printed_edge_count(G):
    """Edge count as the original prints it: entries whose neighbour id is larger."""
    return sum(1 for u, w in G.edges() if u < w)


class PatrolGraph:
    """Read-only lookup tables over a patrol graph, shared by all algorithms.

    Attributes:
        G: the underlying networkx.MultiDiGraph.
        n: vertex count.
        name: map name.
        pos: (n, 2) array of vertex positions in metres.
        pos_px: (n, 2) array of pixel coordinates as in the file.
        neighbors: ``neighbors[u]`` = list of ``(w, cost_px)`` in file order (multi-edges kept).
        derived: tables other modules derive from this graph and keep with it, computed on
            first use and keyed by their owner (e.g. ``"cgg_route"``, ``"dta_path_hops"``,
            ``"dta_decoded"``). They live as long as the graph: one simulation, or the runs
            of one map in a campaign worker, never the whole process.
    """

    def __init__(self, G):
        self.G = G
        self.n = G.number_of_nodes()
        self.name = G.graph.get("name", "graph")
        self.resolution = G.graph["resolution"]
        self.pos = np.array([G.nodes[v]["pos"] for v in range(self.n)], dtype=float)
        self.pos_px = np.array([(G.nodes[v]["x_px"], G.nodes[v]["y_px"])
                                for v in range(self.n)], dtype=float)
        self.neighbors = [[(w, d["cost_px"]) for _, w, d in out_edges_in_order(G, v)]
                          for v in range(self.n)]
        # cheapest directed cost between adjacent vertices
        self._arc = {}
        for u in range(self.n):
            for w, c in self.neighbors[u]:
                if (u, w) not in self._arc or c < self._arc[(u, w)]:
                    self._arc[(u, w)] = c
        self._nbr_ids = [tuple(dict.fromkeys(w for w, _ in self.neighbors[v]))
                         for v in range(self.n)]
        self._dist = None
        self._next = None
        self._hops = None
        self.derived = {}

    @classmethod
    def load(cls, path, occupancy=None):
        return cls(load_graph(path, occupancy))

    def __len__(self):
        return self.n

    def degree(self, v):
        return len(self.neighbors[v])

    def neighbor_ids(self, v):
        """Distinct neighbour ids of v, in first-listed order (a precomputed tuple)."""
        return self._nbr_ids[v]

    def arc_cost(self, u, w):
        """Cheapest cost (px) of an edge u->w, or None if not adjacent."""
        return self._arc.get((u, w))

    def max_stretch(self):
        """Largest ratio of an edge's straight length to its cost (both in metres), at least
        1: a robot driven along the graph at ``speed`` (cost per second) moves at most
        ``speed * max_stretch()`` in the plane. inf if an edge of cost 0 joins two places."""
        worst = 1.0
        for (u, w), c in self._arc.items():
            length = math.hypot(*(self.pos[w] - self.pos[u]))
            if length > 0.0:
                worst = max(worst, length / (c * self.resolution) if c > 0 else math.inf)
        return worst

    def edge_costs(self):
        """All directed edge costs (px), one per neighbour entry."""
        return [c for u in range(self.n) for _, c in self.neighbors[u]]

    def _all_pairs(self):
        if self._dist is None:
            self._dist, self._next = shortest_path_tables(self.n, self._arc)

    @property
    def dist(self):
        """(n, n) array of shortest-path costs in pixels (inf if unreachable)."""
        d = self._dist
        if d is None:                  # read in every decision: no call once computed
            self._all_pairs()
            d = self._dist
        return d

    def path(self, u, v):
        """Shortest path u..v (list of vertex ids, both ends included)."""
        self._all_pairs()
        if u == v:
            return [u]
        if self._next[u, v] < 0:
            return None
        p = [u]
        while p[-1] != v:
            p.append(int(self._next[p[-1], v]))
        return p

    @property
    def hops(self):
        """(n, n) array of hop counts (edges on a fewest-edge path)."""
        if self._hops is None:
            self._hops = hop_table(self.n, self._arc)
        return self._hops

    def nearest_vertex(self, x, y):
        """Vertex minimising ``|dx| + |dy|`` to (x, y) metres (first minimum, as the original)."""
        d = np.abs(self.pos[:, 0] - x) + np.abs(self.pos[:, 1] - y)
        return int(np.argmin(d))
