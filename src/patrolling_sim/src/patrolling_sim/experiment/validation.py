"""Checks shared by the experiment runner and the graph-level simulator, so both give the
same one-line errors (:class:`PatrolInputError`) for the same bad input, before anything
starts.
"""
import logging
import math
import os
import subprocess

from patrolling_sim.common import paths
from patrolling_sim.model import map_bundle
from patrolling_sim.common.errors import PatrolInputError
import hashlib
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.model.graph import load_graph
from patrolling_sim.startpos.initial_poses import load_initial_poses
from patrolling_sim.startpos.resolve import start_positions
from spqrel_nav_lite.mapio import load_map
from spqrel_nav_lite.planner_grid import planner_shape
import yaml

log = logging.getLogger(__name__)

#: Memory of a full-stack run, peak proportional set size (PSS) of the whole process tree, MB,
#: by part, as measured by bench/runner_bench.py (its notes: bench/notes/runner.md, "Memory
#: estimate"). A navigation process costs ``nav_process`` plus ``nav_per_mcell`` per million
#: planner cells (the planner's cost grid and graph dominate); its plan cache comes on top: a
#: navigation function (8 bytes per planner cell) per patrol vertex (only patrol goals get
#: an entry, docs/navigation.md), in a per-robot move_base at most ``robot_nav_cache`` (its
#: ``~plan_cache_mb``), in a nav_host all of them (the runner sets ``~plan_cache_goals``).
#: Update these figures when the benchmark is re-run.
MEMORY_MB = {
    "fixed": 350.0,              # master, simulator, map server, monitor, the agents' process
    "agent_process": 60.0,       # an agent process per robot (--processes separate, *-separate)
    "nav_process": 70.0,         # robot_nav, move_base or nav_host, before the map
    "nav_per_mcell": 370.0,      # per million planner cells (0.1 m), in each such process
    "localiser_process": 60.0,   # amcl / fake_localization in a process of its own (separate)
    "robot_in_host": 30.0,       # each robot hosted by a nav_host
    "robot_nav_cache": 32.0,     # a per-robot move_base's ~plan_cache_mb
}


PROCESS_MODES = ("shared", "separate", "pooled", "pooled-separate")


#: ``speedup`` of ``--speedup auto``: the abstract world steps as soon as its clock holds
#: allow (its ``~speedup`` 0), the pace the machine holds
AUTO_PACE = 0.0


def pace_value(value, where):
    """``speedup`` given as ``value``: a number > 0, or ``auto`` (:data:`AUTO_PACE`).

    Raises:
        PatrolInputError: one line naming ``where``.
    """
    if isinstance(value, str) and value.strip().lower() == "auto":
        return AUTO_PACE
    try:
        f = None if isinstance(value, bool) else float(value)
    except (TypeError, ValueError):
        f = None
    if f is None or not 0 < f < math.inf:
        raise PatrolInputError(f"{where}: must be a number > 0 or auto, got {value!r}")
    return f


def resolve_pace(speedup, nav):
    """The pace of a run in world ``nav``: ``speedup`` None (not given) is auto in the
    abstract world (its figures do not depend on the pace, docs/pace.md) and 1 elsewhere.

    Raises:
        PatrolInputError: one line, for auto outside the abstract world.
    """
    if speedup is None:
        return AUTO_PACE if nav == "abstract" else 1.0
    if speedup == AUTO_PACE and nav != "abstract":
        raise PatrolInputError(
            f"argument --speedup: auto needs --nav abstract (with --nav {nav} the figures "
            f"depend on the pace, docs/pace.md: give a number, e.g. 4)")
    return speedup


def process_layout(processes, robots):
    """(agents, nav, hosts) of a ``--processes`` value: agents ``shared`` (one patrol_agents)
    or ``separate`` (patrol_agent per robot); nav ``robot_nav`` (one per robot), ``separate``
    (amcl/fake_localization + move_base per robot) or ``pooled`` (``hosts`` nav_host
    processes). Raises PatrolInputError with one line when the value is bad."""
    mode, sep, k = str(processes).partition(":")
    if mode not in PROCESS_MODES or (sep and not mode.startswith("pooled")):
        raise PatrolInputError(f"argument --processes: must be one of shared, separate, "
                               f"pooled[:K], pooled-separate[:K], got '{processes}'")
    if not mode.startswith("pooled"):
        return mode, ("robot_nav" if mode == "shared" else "separate"), 0
    if sep:
        if not k.isdigit() or not 1 <= int(k) <= max(1, robots):
            raise PatrolInputError(f"argument --processes: K in '{processes}' must be an "
                                   f"integer from 1 to the number of robots ({robots})")
        hosts = int(k)
    else:
        hosts = 1 if robots <= 8 else 2
    return ("shared" if mode == "pooled" else "separate"), "pooled", min(hosts, robots)


def memory_parts(robots, processes="shared", planner_cells=0, n_vertices=0,
                 nav="spqrel_nav_lite"):
    """The memory estimate of a run by part: [(text, MB)], from :data:`MEMORY_MB` and the
    map's ``planner_cells`` (:func:`map_memory_figures`) and patrol vertices. The abstract
    world has no navigation processes; the stock ROS navigation (``nav`` "ros") is counted
    like ours."""
    m = MEMORY_MB
    agents, layout, hosts = process_layout(processes, robots)
    parts = [(f"{m['fixed']:.0f} MB fixed", m["fixed"])]
    if agents == "separate":
        parts.append((f"{robots} agent processes x {m['agent_process']:.0f} MB",
                      robots * m["agent_process"]))
    if nav == "abstract":
        return parts
    process = m["nav_process"] + m["nav_per_mcell"] * planner_cells / 1e6
    cache = n_vertices * planner_cells * 8 / 2**20     # a navigation function per vertex
    if layout == "pooled":
        host = process + cache
        parts.append((f"{hosts} nav_host x {host:.0f} MB", hosts * host))
        parts.append((f"{robots} robots x {m['robot_in_host']:.0f} MB",
                      robots * m["robot_in_host"]))
    else:
        robot = process + min(m["robot_nav_cache"], cache) + \
            (m["localiser_process"] if layout == "separate" else 0.0)
        parts.append((f"{robots} robots' navigation x {robot:.0f} MB", robots * robot))
    return parts


def memory_figures(omap, graph):
    """(planner cells, patrol vertices) of a loaded map (OccupancyMap) and its patrol graph:
    what the navigation's memory depends on."""
    _, w, h = planner_shape(omap.width, omap.height, omap.resolution)
    return w * h, graph.number_of_nodes()


def map_memory_figures(map_arg):
    """:func:`memory_figures` of ``map_arg`` (a shipped map's name or a yaml path), read from
    its files. The map and graph files must be valid (they are checked before this is
    called)."""
    yaml_path, graph_path = paths.map_files(map_arg)
    return memory_figures(load_map(yaml_path), load_graph(graph_path, warn=False))


def check_map_files(map_arg, what="argument --map"):
    """(yaml_path, graph_path) of ``map_arg``; both must exist."""
    try:
        yaml_path, graph_path = paths.map_files(map_arg)
    except PatrolInputError as e:
        raise PatrolInputError(f"{what}: {e}") from None
    for p in (yaml_path, graph_path):
        if not os.path.isfile(p):
            raise PatrolInputError(f"{what}: '{map_arg}': file {p} not found")
    return yaml_path, graph_path


def strategy_params(params, policy):
    """The strategy's params of a run: a copy of ``params`` with ``policy`` (a policy file,
    as an absolute path) when it is set; the same in graph mode, the runner and campaigns."""
    out = dict(params or {})
    if policy:
        out["policy"] = os.path.abspath(os.path.expanduser(str(policy)))
    return out


def check_writable_dir(path, what="argument --results-dir"):
    """Create ``path`` if needed and check a file can be written in it."""
    try:
        os.makedirs(path, exist_ok=True)
        probe = os.path.join(path, f".write_probe_{os.getpid()}")
        with open(probe, "w") as f:
            f.write("")
        os.remove(probe)
    except OSError as e:
        raise PatrolInputError(f"{what}: '{path}' is not writable ({e.strerror})") from None


def team_size_warning(robots, n_vertices, map_name):
    """The warning line when the team is larger than the graph (robots share vertices), or
    None."""
    if robots > n_vertices:
        return (f"warning: {robots} robots on '{map_name}' with {n_vertices} vertices: "
                f"robots must share vertices (expect many interferences)")
    return None


#: sim s a live robot can go without a visit in ROS mode when a failed teammate's body blocks
#: its goal vertex (docs/scenarios.md, "a failed robot's body blocks a vertex"): 4 navigation
#: attempts (the first and the agent's 3 resends) of about 30 s each with the navigation's
#: defaults (2 s blocked_patience, 3 recoveries of at most 7 s, 2 s again after each), the
#: 1-s back-ups, and the trip to the next vertex
BLOCKED_VERTEX_SILENCE = 150.0


def failure_timeout_warning(failures, nav, dead_robot_timeout):
    """The warning line when a run with robot failures (``failures``: the schedule, empty
    without) in a world with bodies (any ``nav`` but ``abstract``) declares a robot dead after
    fewer sim seconds than a live robot can spend on a vertex a failed one blocks, or None.
    A ``dead_robot_timeout`` of 0 declares no robot dead: nothing to warn about."""
    if not failures or nav == "abstract" or not 0 < dead_robot_timeout < BLOCKED_VERTEX_SILENCE:
        return None
    return (f"warning: --dead-robot-timeout {dead_robot_timeout:g} s with robot failures: a "
            f"teammate whose goal vertex a failed robot blocks can go about "
            f"{BLOCKED_VERTEX_SILENCE:g} s without a visit, and the run would end FAIL "
            f"naming it (docs/scenarios.md); give at least {BLOCKED_VERTEX_SILENCE:g} s")


def available_memory_mb():
    """MemAvailable of /proc/meminfo in MB (None if unknown)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


def memory_estimate_mb(robots, processes="shared", planner_cells=0, n_vertices=0,
                       nav="spqrel_nav_lite"):
    """MB a run needs (peak PSS of its process tree), the sum of :func:`memory_parts`."""
    return sum(mb for _, mb in memory_parts(robots, processes, planner_cells, n_vertices, nav))


def check_memory(robots, processes="shared", planner_cells=0, n_vertices=0,
                 nav="spqrel_nav_lite", force=False, available=None):
    """Error (unless ``force``) when the estimate exceeds the machine's available memory."""
    parts = memory_parts(robots, processes, planner_cells, n_vertices, nav)
    need = sum(mb for _, mb in parts)
    avail = available_memory_mb() if available is None else available
    if avail is None or need <= avail:
        return need
    detail = " + ".join(text for text, _ in parts)
    msg = (f"argument --robots: {robots} robots need about {need / 1024:.1f} GB on this map "
           f"({detail}, measured), the machine has {avail / 1024:.1f} GB available")
    if not force:
        raise PatrolInputError(msg + "; give --force to try anyway")
    log.warning("%s; trying anyway (--force)", msg)
    return need


def check_ros_navigation(loc, env=None):
    """``--nav ros`` needs the ROS navigation packages (move_base, and amcl or
    fake_localization): fail at once, in one line, when rospack cannot find them."""
    needed = ["move_base", "amcl" if loc == "AMCL" else "fake_localization"]
    missing = []
    for pkg in needed:
        try:
            r = subprocess.run(["rospack", "find", pkg], env=env, capture_output=True,
                               timeout=60)
            ok = r.returncode == 0
        except (OSError, subprocess.TimeoutExpired):
            ok = False
        if not ok:
            missing.append(pkg)
    if missing:
        raise PatrolInputError(f"argument --nav: 'ros' needs the ROS packages "
                               f"{', '.join(missing)}, not installed (rospack cannot find "
                               f"them); use --nav spqrel_nav_lite")


def check_start_positions(map_arg, robots, initpos, what="argument --robots", alg=None,
                          seed=0, bundle=None):
    """The team's start positions, checked: the shared check of the runner and graph mode.

    Args:
        map_arg: a shipped map's name or a path to its yaml/.graph.
        robots: team size.
        initpos: the ``initpos`` setting, any form of
            :func:`patrolling_sim.startpos.resolve.start_positions` (a start file is
            resolved against the map's folder).
        what: unused (kept for callers naming the argument).
        alg: the algorithm (``optimised``).
        seed: the run's seed (``random``).
        bundle: the map's (OccupancyMap, graph) if already loaded
            (:func:`patrolling_sim.model.map_bundle.load_map_bundle`).

    Returns:
        (positions, PatrolGraph): ``robots`` (x, y) in metres and the map's patrol graph.

    Raises:
        PatrolInputError: one line when the start positions cannot be placed or the
        setting is malformed.
    """
    occ, G = bundle or map_bundle.load_map_bundle(map_arg)
    table_path = paths.initial_poses_file()
    pg = PatrolGraph(G)
    map_dir = os.path.dirname(os.path.abspath(paths.map_files(map_arg)[0]))
    pos, _ = start_positions(paths.map_name(map_arg), robots, pg, occ, initpos,
                             load_initial_poses(table_path), table_path, alg=alg, seed=seed,
                             map_dir=map_dir)
    return pos, pg


def result_map_name(map_arg):
    """The name results of ``map_arg`` are filed under: a shipped map's own name; for any
    other map its name plus ``-`` and the first 8 hex digits of a SHA-1 of its yaml, image and
    .graph, so a user's map called ``grid`` never mixes with the shipped grid."""
    name = paths.map_name(map_arg)
    yaml_path, graph_path = paths.map_files(map_arg)
    shipped = os.path.join(paths.maps_dir(), name, name + ".yaml")
    if os.path.abspath(yaml_path) == os.path.abspath(shipped):
        return name
    h = hashlib.sha1()
    files = [yaml_path, graph_path]
    try:
        with open(yaml_path, encoding="utf-8") as f:
            image = (yaml.safe_load(f) or {}).get("image")
        if image:
            files.append(os.path.join(os.path.dirname(yaml_path), str(image)))
    except (OSError, ValueError, AttributeError, yaml.YAMLError):
        pass
    for p in files:
        try:
            with open(p, "rb") as f:
                h.update(f.read())
        except OSError:
            pass
    return f"{name}-{h.hexdigest()[:8]}"
