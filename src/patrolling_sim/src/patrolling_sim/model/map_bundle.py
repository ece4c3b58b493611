"""A map loaded by name: its occupancy grid and patrol graph (shipped maps or paths, as
:func:`patrolling_sim.common.paths.map_files` resolves them)."""
import functools
import os

from patrolling_sim.common.paths import map_files
from patrolling_sim.model.graph import load_graph
from spqrel_nav_lite.mapio import load_map


def vertex_count(name):
    """Number of vertices of a map's patrol graph (its file is parsed again only when it
    changed: :func:`_graph_vertex_count` is a pure function of the file's path and stamp).

    Raises:
        PatrolInputError: unknown map or unreadable graph file.
    """
    path = map_files(name)[1]
    try:
        st = os.stat(path)
    except OSError:
        st = None
    return _graph_vertex_count(path, st and st.st_size, st and st.st_mtime_ns)


@functools.lru_cache(maxsize=256)
def _graph_vertex_count(path, _size, _mtime_ns):
    return load_graph(path, warn=False).number_of_nodes()


def load_map_bundle(name):
    """Load a map's occupancy grid and patrol graph; vertices on non-free cells warn.

    Returns:
        (OccupancyMap, networkx.MultiDiGraph)
    """
    yaml_path, graph_path = map_files(name)
    occ = load_map(yaml_path)
    G = load_graph(graph_path, occupancy=occ)
    return occ, G
