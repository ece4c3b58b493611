"""Random patrol graphs for the learning environment (docs/learning.md, "Random graphs"):
seeded, connected, planar-ish graphs with positions in metres, written as an ordinary map
(``.graph``, ``.yaml``, ``.pgm``) so that every part of graph mode (start positions, the
range communication model, drawing) works on them as on a shipped map.

The generator: ``n`` vertices drawn uniformly in a ``size`` x ``size`` m square, at least
``spacing`` m apart (rejection sampling); the Euclidean minimum spanning tree (connected);
then the other pairs closer than ``radius`` m, shortest first, while both ends have fewer
than ``max_degree`` neighbours. Every edge costs its straight length (rounded to the pixel).
The map is free space with a wall around it.
"""
import math
import os
import random
from dataclasses import dataclass

import networkx as nx

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.model.graph import DIRECTIONS, write_graph

RESOLUTION = 0.1          # m per pixel of the written map
MARGIN = 2.0              # m of free space between the square and the wall


@dataclass
class RandomGraphSpec:
    """Parameters of :func:`random_patrol_graph` (the ``random:...`` map form)."""
    n: int = 30
    size: float = 40.0
    radius: float = 12.0
    max_degree: int = 4
    spacing: float = 3.0

    def check(self):
        if self.n < 2:
            raise PatrolInputError(f"random graph: n must be >= 2, got {self.n}")
        if self.size <= 0 or self.radius <= 0 or self.spacing < 0:
            raise PatrolInputError("random graph: size and radius must be > 0, spacing >= 0")
        if self.max_degree < 2:
            raise PatrolInputError(
                f"random graph: max_degree must be >= 2, got {self.max_degree}")
        if self.n * math.pi * (self.spacing / 2) ** 2 > 0.5 * self.size ** 2:
            raise PatrolInputError(f"random graph: {self.n} vertices {self.spacing:g} m apart "
                                   f"do not fit in {self.size:g} x {self.size:g} m")
        return self


def parse_random_spec(text: str) -> RandomGraphSpec:
    """``random`` or ``random:n=30,size=40,radius=12,max_degree=4,spacing=3``."""
    spec = RandomGraphSpec()
    body = text.split(":", 1)[1] if ":" in text else ""
    for item in filter(None, (s.strip() for s in body.split(","))):
        key, _, value = item.partition("=")
        key = key.strip()
        if key not in spec.__dataclass_fields__ or not value:
            raise PatrolInputError(f"argument map: bad random graph item '{item}' (known: "
                                   f"{', '.join(spec.__dataclass_fields__)})")
        kind = type(getattr(spec, key))
        try:
            setattr(spec, key, kind(value))
        except ValueError:
            raise PatrolInputError(f"argument map: '{key}' must be a number, got '{value}'") \
                from None
    return spec.check()


def _points(spec: RandomGraphSpec, rng: random.Random):
    pts = []
    tries = 0
    while len(pts) < spec.n:
        tries += 1
        if tries > 200 * spec.n:
            raise PatrolInputError(f"random graph: could not place {spec.n} vertices "
                                   f"{spec.spacing:g} m apart; lower n or spacing")
        p = (rng.uniform(0, spec.size), rng.uniform(0, spec.size))
        if all(math.hypot(p[0] - q[0], p[1] - q[1]) >= spec.spacing for q in pts):
            pts.append(p)
    return pts


def _direction(dx, dy):
    k = int(round(math.atan2(dy, dx) / (math.pi / 4))) % 8      # 0: east, counter-clockwise
    return DIRECTIONS[(2 - k) % 8]


def spanning_tree(n, order, max_degree):
    """(edges, degree) of a spanning tree over ``order`` (((u, w), length) pairs, shortest
    first): Kruskal's minimum spanning tree, skipping an edge that would give a vertex more
    than ``max_degree`` neighbours (the tree is the minimum one whenever that respects the
    limit); components still apart are then joined by their shortest edge, between vertices
    under the limit when there is one."""
    comp = list(range(n))

    def find(v):
        while comp[v] != v:
            comp[v] = comp[comp[v]]
            v = comp[v]
        return v
    edges, degree = set(), [0] * n
    for strict in (True, False):
        for (u, w), _ in order:
            if find(u) == find(w) or (strict and max(degree[u], degree[w]) >= max_degree):
                continue
            if not strict and max(degree[u], degree[w]) >= max_degree and any(
                    find(a) != find(b) and max(degree[a], degree[b]) < max_degree
                    for (a, b), _ in order):
                continue
            comp[find(u)] = find(w)
            edges.add((u, w))
            degree[u] += 1
            degree[w] += 1
    return edges, degree


def random_patrol_graph(seed: int, spec: RandomGraphSpec = None, name: str = "random"):
    """A connected patrol graph (networkx.MultiDiGraph in :mod:`patrolling_sim.model.graph`'s
    form) drawn from ``seed`` with ``spec`` (module docstring); the same seed and spec
    give the same graph."""
    spec = (spec or RandomGraphSpec()).check()
    rng = random.Random(seed)
    pts = _points(spec, rng)
    px = [(int(round((x + MARGIN) / RESOLUTION)), int(round((y + MARGIN) / RESOLUTION)))
          for x, y in pts]
    length = {}
    for u in range(spec.n):
        for w in range(u + 1, spec.n):
            length[(u, w)] = math.hypot(px[w][0] - px[u][0], px[w][1] - px[u][1])
    order = sorted(length.items(), key=lambda kv: (kv[1], kv[0]))
    edges, degree = spanning_tree(spec.n, order, spec.max_degree)
    for (u, w), d in order:
        if (u, w) in edges or d * RESOLUTION > spec.radius:
            continue
        if degree[u] < spec.max_degree and degree[w] < spec.max_degree:
            edges.add((u, w))
            degree[u] += 1
            degree[w] += 1
    side = int(math.ceil((spec.size + 2 * MARGIN) / RESOLUTION))
    G = nx.MultiDiGraph(name=name, path=name + ".graph", width_px=side, height_px=side,
                        resolution=RESOLUTION, offset_x=0.0, offset_y=0.0)
    for v, (x, y) in enumerate(px):
        G.add_node(v, x_px=x, y_px=y, pos=(x * RESOLUTION, y * RESOLUTION))
    for u in range(spec.n):
        for w in sorted(w for e in edges if u in e for w in e if w != u):
            c = max(1, int(round(length[(min(u, w), max(u, w))])))
            dx, dy = px[w][0] - px[u][0], px[w][1] - px[u][1]
            G.add_edge(u, w, direction=_direction(dx, dy), cost_px=c, cost_m=c * RESOLUTION)
    return G


def write_map_bundle(G, folder: str, name: str) -> str:
    """Write ``G`` as the map ``folder/name/name.{graph,yaml,pgm}`` (free space inside a
    one-pixel wall, the graph's size); returns the ``.yaml`` path, usable as ``--map``."""
    d = os.path.join(folder, name)
    os.makedirs(d, exist_ok=True)
    w, h = int(G.graph["width_px"]), int(G.graph["height_px"])
    rows = bytearray(b"\xfe" * (w * h))
    for c in range(w):
        rows[c] = rows[(h - 1) * w + c] = 0
    for r in range(h):
        rows[r * w] = rows[r * w + w - 1] = 0
    with open(os.path.join(d, name + ".pgm"), "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (w, h) + bytes(rows))
    with open(os.path.join(d, name + ".yaml"), "w", encoding="utf-8") as f:
        f.write(f"image: {name}.pgm\nresolution: {G.graph['resolution']}\n"
                f"origin: [{G.graph['offset_x']}, {G.graph['offset_y']}, 0.0]\nnegate: 0\n"
                "occupied_thresh: 0.65\nfree_thresh: 0.19\n")
    write_graph(G, os.path.join(d, name + ".graph"))
    return os.path.join(d, name + ".yaml")
