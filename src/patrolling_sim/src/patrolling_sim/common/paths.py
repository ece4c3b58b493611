"""Where the shipped data lives (maps/, params/, MSP/) and how map names resolve.

The data root is ``$PATROLLING_SIM_DATA`` if set, else the workspace root found from this
file (``<root>/src/patrolling_sim/src/patrolling_sim/common/paths.py``).
"""
import functools
import os

from patrolling_sim.common.errors import PatrolInputError


def data_root():
    env = os.environ.get("PATROLLING_SIM_DATA")
    if env:
        return os.path.abspath(env)
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.abspath(os.path.join(here, "..", "..", "..", "..", ".."))


def maps_dir():
    return os.path.join(data_root(), "maps")


def available_maps():
    d = maps_dir()
    if not os.path.isdir(d):
        return []
    return sorted(m for m in os.listdir(d)
                  if os.path.isfile(os.path.join(d, m, m + ".graph")))


def map_files(name):
    """(yaml_path, graph_path) of a shipped map, or of a map given as a directory or as a
    path to its ``.yaml`` / ``.graph`` file (the other file is looked up beside it).

    Raises:
        PatrolInputError: unknown map name (the message lists the available ones).
    """
    if os.sep in name or name.endswith((".yaml", ".graph")):
        base = name[:-5] if name.endswith(".yaml") else (
            name[:-6] if name.endswith(".graph") else os.path.join(
                name.rstrip(os.sep), os.path.basename(name.rstrip(os.sep))))
        return base + ".yaml", base + ".graph"
    d = os.path.join(maps_dir(), name)
    if not os.path.isdir(d):
        raise PatrolInputError(
            f"unknown map '{name}' (available: {', '.join(available_maps()) or 'none'})")
    return os.path.join(d, name + ".yaml"), os.path.join(d, name + ".graph")


def map_name(name):
    """Plain map name from a name or a path."""
    base = os.path.basename(name.rstrip(os.sep))
    for ext in (".yaml", ".graph"):
        if base.endswith(ext):
            base = base[: -len(ext)]
    return base


def initial_poses_file():
    return os.path.join(data_root(), "params", "initial_poses.txt")


def dta_params_file(name):
    return os.path.join(data_root(), "params", "DTA", name + ".params")


def msp_route_file(map_name_, n_robots, robot_id):
    return os.path.join(data_root(), "MSP", map_name_, f"{map_name_}_{n_robots}_{robot_id}")
