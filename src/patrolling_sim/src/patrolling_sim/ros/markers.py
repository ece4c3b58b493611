"""Live patrol-graph markers for rviz (``/patrol_graph_markers``), built without a master.

:func:`build_marker_array` returns a ``visualization_msgs/MarkerArray`` in frame ``map``:

- namespace ``vertices``: one SPHERE per vertex (id = vertex), coloured by its current
  idleness on a green (0) -> red (max current idleness) scale;
- namespace ``vertex_ids``: one TEXT_VIEW_FACING per vertex with its id, above the sphere;
- namespace ``edges``: one LINE_LIST (id 0) with every undirected edge once.
"""
import genpy
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

SPHERE_DIAMETER = 0.6    # m
TEXT_HEIGHT = 0.5        # m
EDGE_WIDTH = 0.08        # m


def idleness_color(idleness, max_idleness):
    """Green at 0, red at ``max_idleness`` (all green if the max is 0)."""
    r = 0.0 if max_idleness <= 0 else min(1.0, max(0.0, idleness / max_idleness))
    return ColorRGBA(r=r, g=1.0 - r, b=0.0, a=1.0)


def undirected_edges(graph):
    """Sorted distinct (u, w) pairs with u < w (multi-edges and both directions merged)."""
    return sorted({(min(u, w), max(u, w)) for u in range(graph.n)
                   for w, _ in graph.neighbors[u] if u != w})


def build_marker_array(graph, idleness, stamp=None, frame_id="map"):
    """MarkerArray of ``graph`` (a :class:`patrolling_sim.model.graph.PatrolGraph`) with vertices
    coloured by ``idleness`` (one value per vertex, seconds)."""
    if len(idleness) != graph.n:
        raise ValueError(f"idleness has {len(idleness)} values for {graph.n} vertices")
    stamp = stamp if stamp is not None else genpy.Time()
    top = max(idleness) if graph.n else 0.0
    out = MarkerArray()

    def base(ns, mid, mtype):
        m = Marker()
        m.header.frame_id = frame_id
        m.header.stamp = stamp
        m.ns = ns
        m.id = mid
        m.type = mtype
        m.action = Marker.ADD
        m.pose.orientation.w = 1.0
        return m

    for v in range(graph.n):
        x, y = float(graph.pos[v][0]), float(graph.pos[v][1])
        s = base("vertices", v, Marker.SPHERE)
        s.pose.position.x, s.pose.position.y = x, y
        s.scale.x = s.scale.y = s.scale.z = SPHERE_DIAMETER
        s.color = idleness_color(float(idleness[v]), top)
        out.markers.append(s)
        t = base("vertex_ids", v, Marker.TEXT_VIEW_FACING)
        t.pose.position.x, t.pose.position.y = x, y
        t.pose.position.z = SPHERE_DIAMETER
        t.scale.z = TEXT_HEIGHT
        t.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
        t.text = str(v)
        out.markers.append(t)
    e = base("edges", 0, Marker.LINE_LIST)
    e.scale.x = EDGE_WIDTH
    e.color = ColorRGBA(r=0.2, g=0.4, b=1.0, a=0.8)
    for u, w in undirected_edges(graph):
        e.points.append(Point(x=float(graph.pos[u][0]), y=float(graph.pos[u][1]), z=0.0))
        e.points.append(Point(x=float(graph.pos[w][0]), y=float(graph.pos[w][1]), z=0.0))
    out.markers.append(e)
    return out
