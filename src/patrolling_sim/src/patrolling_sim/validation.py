"""Checks shared by the experiment runner and the graph-level simulator, so both give the
same one-line errors (:class:`PatrolInputError`) for the same bad input, before anything
starts.
"""
import logging
import os
import subprocess

from . import paths
from .errors import PatrolInputError

log = logging.getLogger(__name__)

#: Measured memory of a full-stack run (proportional set size of the whole process tree,
#: MB), from the runner benchmark in docs/BENCHMARKS.md and docs/benchmarks/runner.md
#: (fake localisation, 4x: 907 MB with 4 robots, 1417 with 8, 2017 with 12, i.e. about
#: 140 MB per robot over a fixed 350 MB; ``--processes separate``: 2.7 GB with 12 robots,
#: about 200 MB per robot). Update these figures when the benchmark is re-run.
#: ``pooled`` / ``pooled-separate`` (navigation in nav_host processes, docs/navigation.md):
#: per robot and per nav_host process, the largest measured (docs/benchmarks/runner.md,
#: "Layouts"): navigation PSS per robot 37-41 MB on grid with 12 robots, 60 MB on cumberland
#: with 32, 78 MB on broughton with 64 (whose plan caches hold all 163 goals, 0.8 GB each);
#: whole runs 0.8, 2.3 and 5.5 GB. One agent process per robot adds about 60 MB per robot
#: (shared -> separate above).
MEMORY_MB = {
    "fixed": 350.0,                     # master, simulator, map server, monitor, runner
    "per_robot": {"shared": 140.0, "separate": 200.0, "pooled": 80.0,
                  "pooled-separate": 140.0},
    "per_nav_host": 150.0,
}


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


def _layout_figures(robots, processes):
    """(MB per robot, nav_host processes, text of the fixed part) of a --processes value."""
    mode = str(processes).partition(":")[0]
    per = MEMORY_MB["per_robot"].get(mode, MEMORY_MB["per_robot"]["shared"])
    hosts = 0
    if mode.startswith("pooled"):
        from .runner.config import process_layout
        try:
            hosts = process_layout(processes, robots)[2]
        except PatrolInputError:
            hosts = 1
    fixed = MEMORY_MB["fixed"] + hosts * MEMORY_MB["per_nav_host"]
    return per, hosts, fixed


def memory_estimate_mb(robots, processes="shared"):
    per, _, fixed = _layout_figures(robots, processes)
    return fixed + per * robots


def check_memory(robots, processes="shared", force=False, available=None):
    """Error (unless ``force``) when the estimate exceeds the machine's available memory."""
    need = memory_estimate_mb(robots, processes)
    avail = available_memory_mb() if available is None else available
    if avail is None or need <= avail:
        return need
    per, hosts, fixed = _layout_figures(robots, processes)
    host_text = f" + {hosts} nav_host x {MEMORY_MB['per_nav_host']:.0f} MB" if hosts else ""
    msg = (f"argument --robots: {robots} robots need about {need / 1024:.1f} GB "
           f"({MEMORY_MB['fixed']:.0f} MB{host_text} + {robots} x {per:.0f} MB, measured), "
           f"the machine has "
           f"{avail / 1024:.1f} GB available")
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


def check_start_positions(map_arg, robots, initpos, what="argument --robots", alg=None):
    """The team's start positions (from params/initial_poses.txt or computed); a one-line
    error when they cannot be placed."""
    from .graph import PatrolGraph
    from .initial_poses import load_initial_poses, start_positions
    occ, G = paths.load_map_bundle(map_arg)
    table_path = paths.initial_poses_file()
    pg = PatrolGraph(G)
    pos, _ = start_positions(paths.map_name(map_arg), robots, pg, occ, initpos,
                             load_initial_poses(table_path), table_path, alg=alg)
    return pos, pg


def result_map_name(map_arg):
    """The name results of ``map_arg`` are filed under: a shipped map's own name; for any
    other map its name plus ``-`` and the first 8 hex digits of a SHA-1 of its yaml, image and
    .graph, so a user's map called ``grid`` never mixes with the shipped grid."""
    import hashlib
    name = paths.map_name(map_arg)
    yaml_path, graph_path = paths.map_files(map_arg)
    shipped = os.path.join(paths.maps_dir(), name, name + ".yaml")
    if os.path.abspath(yaml_path) == os.path.abspath(shipped):
        return name
    h = hashlib.sha1()
    files = [yaml_path, graph_path]
    try:
        import yaml
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
