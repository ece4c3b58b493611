"""Where the package's data and programs are, in a source checkout or an install space, and
how map names resolve.

Two layouts are recognised from this file's place:

- a **source checkout** (also its catkin devel space, which runs the sources):
  ``<root>/src/patrolling_sim/src/patrolling_sim/common/paths.py``; data in ``<root>/maps``,
  ``<root>/params``, ``<root>/MSP``, programs in ``<root>/scripts``, environment
  ``<root>/devel/setup.bash``;
- an **install space** (``catkin_make install``):
  ``<prefix>/lib/python3/dist-packages/patrolling_sim/common/paths.py``; data in
  ``<prefix>/share/patrolling_sim``, programs in ``<prefix>/lib/patrolling_sim``, environment
  ``<prefix>/setup.bash``.

``$PATROLLING_SIM_DATA``, if set, overrides where the data (maps, params, MSP) is read.
"""
import functools
import os

from patrolling_sim.common.errors import PatrolInputError

PACKAGE = "patrolling_sim"


def package_parent():
    """The folder that holds the ``patrolling_sim`` package (what ``PYTHONPATH`` must name)."""
    return os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def source_root():
    """The repository root when the package runs from its source checkout, else None."""
    root = os.path.abspath(os.path.join(package_parent(), "..", "..", ".."))
    return root if os.path.isfile(os.path.join(root, "src", PACKAGE, "package.xml")) else None


def install_prefix():
    """The install prefix when the package runs from a catkin install space, else None."""
    prefix = os.path.abspath(os.path.join(package_parent(), "..", "..", ".."))
    share = os.path.join(prefix, "share", PACKAGE, "package.xml")
    return prefix if os.path.isfile(share) else None


@functools.lru_cache(maxsize=1)
def _layout():
    """("source", root) or ("install", prefix), found once per process (every map lookup
    asks). Raises PatrolInputError in neither (not cached: asked again next time)."""
    root = source_root()
    if root:
        return "source", root
    prefix = install_prefix()
    if prefix:
        return "install", prefix
    raise PatrolInputError(f"cannot tell where {PACKAGE}'s data is: {package_parent()} is "
                           "neither a source checkout nor a catkin install space; set "
                           "PATROLLING_SIM_DATA to the folder holding maps/, params/, MSP/")


def data_root():
    """The folder holding ``maps/``, ``params/`` and ``MSP/``: ``$PATROLLING_SIM_DATA`` if
    set, else the repository root or the install space's ``share/patrolling_sim``."""
    env = os.environ.get("PATROLLING_SIM_DATA")
    if env:
        return os.path.abspath(env)
    kind, where = _layout()
    return where if kind == "source" else os.path.join(where, "share", PACKAGE)


def program(name):
    """The path of one of the package's command-line programs (``start_experiments.py``,
    ``graph_sim.py``, ...): ``scripts/`` of the checkout or ``lib/patrolling_sim`` of the
    install space."""
    kind, where = _layout()
    folder = (os.path.join(where, "scripts") if kind == "source"
              else os.path.join(where, "lib", PACKAGE))
    return os.path.join(folder, name)


def workspace_setup():
    """The ``setup.bash`` that gives ROS processes this workspace's environment: the
    checkout's ``devel/setup.bash`` or the install space's ``setup.bash``."""
    kind, where = _layout()
    return os.path.join(where, "devel", "setup.bash") if kind == "source" else \
        os.path.join(where, "setup.bash")


def results_root():
    """Where results go by default: the checkout's root, or the current folder when the
    package runs from an install space (read-only for its users)."""
    root = source_root()
    return root if root else os.getcwd()


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


def policy_file(name):
    """The shipped policy file ``policies/<name>.npz`` (docs/learning.md)."""
    return os.path.join(data_root(), "policies", name + ".npz")


def msp_route_file(map_name_, n_robots, robot_id):
    return os.path.join(data_root(), "MSP", map_name_, f"{map_name_}_{n_robots}_{robot_id}")
