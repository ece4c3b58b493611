"""Start positions a user states, and random ones: the ``initpos`` forms besides the
original's table (``default``, a lettered variant) and ``optimised``.

Forms (:func:`parse_initpos`):

- ``vertices:V0,V1,...``: robot i starts on vertex Vi, one vertex per robot;
- ``file:PATH``, or a bare value with a path separator or a file extension
  (``starts.txt``; variant names never contain ``/`` or ``.``): a file of start poses or
  vertices, PATH relative to the map's folder unless absolute. Either the original's
  ``initial_poses.txt`` format for one scenario (an ``[InitialPoses]`` section; its key
  ``<map>_<N>`` if present, else its only key) or a plain table, one line per robot:
  ``robot x y`` (a pose in metres) or ``robot vertex``, or a run's own
  ``<prefix>_start_poses.txt`` (``robot x y vertex``: its poses, whose nearest vertices are
  the recorded ones), so a run's starts can be given to another; blank lines and ``#``
  comments are ignored and robots 0..N-1 each appear exactly once;
- ``random``: start vertices drawn uniformly at random from the run's seed
  (:func:`random_start_vertices`), so that a campaign over seeds averages over start
  positions.

A vertex start puts the robot on the vertex's coordinates; a pose start on the pose, and its
start vertex is the vertex nearest to it (as the agents find it, ``docs/protocol.md``).
Checks, before anything starts (:class:`PatrolInputError`, one line naming the value):
vertex ids that do not exist, a count that is not the team size, a malformed file, a robot
on a cell that is not free, off the map, closer to an obstacle than the robot radius, or
closer than the start separation to a robot on another place. Robots sharing a vertex get a
warning (the original allows it), not an error.
"""
import collections
import logging
import math
import os
import random
import re

import numpy as np

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import read_text
from patrolling_sim.startpos.initial_poses import MIN_SEPARATION
from patrolling_sim.startpos.initial_poses import ROBOT_RADIUS
from patrolling_sim.startpos.initial_poses import load_initial_poses

log = logging.getLogger(__name__)

VERTICES = "vertices"
FILE = "file"
RANDOM = "random"
#: the name the errors give the setting (a flag, a YAML key, a campaign value)
WHAT = "argument --initpos"
#: a bare ``initpos`` ending like this names a file (``starts.txt``, ``team.ini``)
_EXTENSION = re.compile(r"\.[A-Za-z0-9]+$")

#: a parsed ``initpos``: ``kind`` one of VERTICES, FILE, RANDOM; ``vertices`` the stated ids
#: (VERTICES); ``path`` the file as given (FILE); ``text`` the setting as given
StartForm = collections.namedtuple("StartForm", "kind vertices path text")
#: one robot's stated start: ``vertex`` (None for a pose) and its place ``x``, ``y`` (m;
#: None for a vertex not resolved yet)
Start = collections.namedtuple("Start", "vertex x y")


def parse_initpos(initpos):
    """The form of an ``initpos`` setting, syntax only.

    Args:
        initpos: the setting (str; an int is read as its text).

    Returns:
        a :data:`StartForm`, or None for the table forms ("default", a lettered variant,
        "optimised"), which :mod:`patrolling_sim.startpos.initial_poses` resolves.

    Raises:
        PatrolInputError: ``vertices:`` without a list of integer ids >= 0, ``file:``
        without a path.
    """
    text = str(initpos if initpos is not None else "").strip()
    if text == RANDOM:
        return StartForm(RANDOM, (), "", text)
    if text.startswith(VERTICES + ":"):
        items = [s.strip() for s in text[len(VERTICES) + 1:].split(",")]
        if not all(re.fullmatch(r"\d+", s) for s in items):
            bad = next(s for s in items if not re.fullmatch(r"\d+", s))
            raise PatrolInputError(f"{WHAT}: '{text}': expected comma-separated vertex ids "
                                   f"(integers >= 0), got '{bad}'")
        return StartForm(VERTICES, tuple(int(s) for s in items), "", text)
    if text.startswith(FILE + ":"):
        path = text[len(FILE) + 1:].strip()
        if not path:
            raise PatrolInputError(f"{WHAT}: '{text}': expected file:PATH")
        return StartForm(FILE, (), path, text)
    if "/" in text or os.sep in text or _EXTENSION.search(text):
        return StartForm(FILE, (), text, text)
    return None


def check_initpos(initpos, robots):
    """Check what can be checked of ``initpos`` without the map: its syntax and, for a
    vertex list, its count against ``robots``. Returns its :data:`StartForm` (None for the
    table forms). Raises PatrolInputError (one line naming the value)."""
    form = parse_initpos(initpos)
    if form is not None and form.kind == VERTICES and len(form.vertices) != robots:
        raise PatrolInputError(f"{WHAT}: '{form.text}' gives {len(form.vertices)} start "
                               f"vertices, the team has {robots} robots")
    return form


def start_file_path(path, map_dir=None):
    """The file a ``file:`` form names: ``path`` itself when absolute, else relative to the
    map's folder ``map_dir`` (the current folder when None)."""
    path = os.path.expanduser(path)
    if os.path.isabs(path) or not map_dir:
        return path
    return os.path.join(map_dir, path)


def initpos_label(initpos, seed):
    """The text that names a run's start in ``_start_poses.txt``: ``--initpos X``, with the
    seed for ``random`` (its draw depends on it)."""
    form = parse_initpos(initpos)
    label = f"--initpos {initpos}"
    return label + f" --seed {seed}" if form is not None and form.kind == RANDOM else label


def _is_ini(text):
    """Whether the first line that is neither blank nor a comment opens an INI section."""
    for line in text.splitlines():
        s = line.strip()
        if s and not s.startswith(("#", ";")):
            return s.startswith("[")
    return False


def _read_ini(path, map_name, n):
    """The poses of an ``initial_poses.txt``-format file: the key ``<map>_<n>`` if present,
    else the only key. Raises PatrolInputError naming the file."""
    table = load_initial_poses(path)
    key = f"{map_name}_{n}".lower()
    if key not in table:
        if len(table) != 1:
            raise PatrolInputError(f"{path}: no key '{key}' and {len(table)} other keys "
                                   f"(give the key '{key}', or a file with one key)")
        key = next(iter(table))
    poses = table[key]
    if len(poses) != n:
        raise PatrolInputError(f"{path}: key '{key}' has {len(poses)} poses, the team has "
                               f"{n} robots")
    return [Start(None, float(x), float(y)) for x, y in poses]


def _table_line(path, k, line):
    """(robot, Start) of line ``k`` of a plain table. Raises PatrolInputError."""
    fields = line.replace(",", " ").split()
    try:
        robot = int(fields[0])
        if len(fields) == 2:
            return robot, Start(int(fields[1]), None, None)
        if len(fields) in (3, 4):           # 4: a run's _start_poses.txt, robot x y vertex
            x, y = float(fields[1]), float(fields[2])
            if len(fields) == 4:
                int(fields[3])
            if math.isfinite(x) and math.isfinite(y):
                return robot, Start(None, x, y)
    except ValueError:
        pass
    raise PatrolInputError(f"{path}:{k}: expected 'robot x y' or 'robot vertex' (integer "
                           f"robot and vertex ids, x and y in metres), got '{line.strip()}'")


def _read_table(path, text, n):
    """The starts of a plain table (module doc), robot 0 first. Raises PatrolInputError:
    a malformed line, a robot twice, a count that is not ``n``, a robot id out of 0..n-1."""
    rows = {}
    for k, line in enumerate(text.splitlines(), start=1):
        line = line.split("#", 1)[0]
        if not line.strip():
            continue
        robot, start = _table_line(path, k, line)
        if robot in rows:
            raise PatrolInputError(f"{path}:{k}: robot {robot} is given twice (first on "
                                   f"line {rows[robot][0]})")
        rows[robot] = (k, start)
    if len(rows) != n:
        raise PatrolInputError(f"{path}: has start positions for {len(rows)} robots, the "
                               f"team has {n}")
    for robot, (k, _) in rows.items():
        if not 0 <= robot < n:
            raise PatrolInputError(f"{path}:{k}: robot {robot} is not in the team (robots 0 "
                                   f"to {n - 1})")
    return [rows[i][1] for i in range(n)]


def read_start_file(path, map_name, n):
    """The stated starts of a start file (module doc) for ``n`` robots on ``map_name``.

    Returns:
        a list of ``n`` :data:`Start` (robot 0 first; vertices not resolved).

    Raises:
        PatrolInputError: a missing or unreadable file, a malformed line or value, a count
        that is not ``n``.
    """
    text = read_text(path, "start positions file")
    if _is_ini(text):
        return _read_ini(path, map_name, n)
    return _read_table(path, text, n)


def usable_vertices(pgraph, occupancy):
    """The vertices where a robot fits: a free cell with the robot radius of clearance (all
    of them without an ``occupancy`` grid)."""
    if occupancy is None:
        return list(range(pgraph.n))
    return [v for v, (x, y) in enumerate(pgraph.pos)
            if occupancy.is_free(x, y) and occupancy.clearance_at(x, y) >= ROBOT_RADIUS]


def random_start_vertices(pgraph, n, seed, usable=None, min_separation=MIN_SEPARATION):
    """``n`` start vertices drawn at random, reproducibly from ``seed``.

    The protocol: the vertices where a robot fits (``usable``, default all) are shuffled
    uniformly by ``random.Random("start-vertices:<seed>")`` (a stream of its own: the
    agents' and the world's draws are not disturbed); robots take them in that order,
    skipping a vertex closer than ``min_separation`` to one already taken. So the robots
    stand on distinct vertices while ``n`` is at most their number; beyond, every such
    vertex holds one robot and the rest are drawn again the same way (each round a new
    shuffle), so robots share vertices as evenly as possible.

    Returns:
        a list of ``n`` vertex ids (the same for the same seed, graph and ``n``).

    Raises:
        PatrolInputError: no vertex where a robot fits.
    """
    usable = list(range(pgraph.n)) if usable is None else list(usable)
    if not usable:
        raise PatrolInputError(f"{WHAT}: 'random': no vertex of '{pgraph.name}' where a robot "
                               f"fits (free cell, {ROBOT_RADIUS} m clearance)")
    rng = random.Random(f"start-vertices:{seed}")
    spread = []
    for v in rng.sample(usable, len(usable)):
        if all(math.dist(pgraph.pos[v], pgraph.pos[w]) >= min_separation for w in spread):
            spread.append(int(v))
    out = list(spread)
    while len(out) < n:
        out += rng.sample(spread, len(spread))
    return out[:n]


def _vertex_starts(starts, pgraph, text):
    """``starts`` with every vertex start given the vertex's coordinates. Raises
    PatrolInputError: a vertex id that is not in the graph (``text``: the setting)."""
    out = []
    for s in starts:
        if s.vertex is None:
            out.append(s)
            continue
        if not 0 <= s.vertex < pgraph.n:
            raise PatrolInputError(f"{WHAT}: '{text}': vertex {s.vertex} does not exist (the "
                                   f"graph of '{pgraph.name}' has vertices 0 to "
                                   f"{pgraph.n - 1})")
        x, y = pgraph.pos[s.vertex]
        out.append(Start(s.vertex, float(x), float(y)))
    return out


def _place_problem(starts, occupancy):
    """None if every robot of ``starts`` (vertices resolved) can stand there, else a
    one-line reason naming the robot and its place: a cell that is not free or off the map,
    less than the robot radius from an obstacle, or closer than the start separation to a
    robot on another place (robots on the same vertex are not compared)."""
    def where(k, s):
        at = f"({s.x:.3f}, {s.y:.3f})"
        return f"robot {k} at {at}" + (f" (vertex {s.vertex})" if s.vertex is not None else "")
    if occupancy is not None:
        for k, s in enumerate(starts):
            state = occupancy.cell_state(s.x, s.y)
            if state == "out-of-map":
                return f"{where(k, s)} is off the map"
            if state != "free":
                return f"{where(k, s)} is on an {state} cell"
            c = occupancy.clearance_at(s.x, s.y)
            if c < ROBOT_RADIUS:
                return (f"{where(k, s)} is {c:.2f} m from an obstacle (needs "
                        f"{ROBOT_RADIUS:.2f} m)")
    p = np.array([(s.x, s.y) for s in starts], dtype=float)
    d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
    for i, j in zip(*np.nonzero(d < MIN_SEPARATION)):
        same = starts[i].vertex is not None and starts[i].vertex == starts[j].vertex
        if i < j and not same:
            return (f"robots {i} and {j} are {d[i, j]:.2f} m apart (needs "
                    f"{MIN_SEPARATION:.2f} m)")
    return None


def _warn_shared(vertices, text):
    """A warning naming the robots that start on one vertex, if any."""
    groups = collections.defaultdict(list)
    for k, v in enumerate(vertices):
        groups[v].append(k)
    shared = [f"robots {', '.join(map(str, ks[:-1]))} and {ks[-1]} start on vertex {v}"
              for v, ks in groups.items() if len(ks) > 1]
    if shared:
        log.warning("--initpos %s: %s (the original allows it; expect interference)",
                    text, "; ".join(shared))


def stated_start_positions(form, map_name, n, pgraph, occupancy, seed=0, map_dir=None):
    """Start positions of the ``initpos`` form ``form`` (:func:`parse_initpos`).

    Args:
        form: a :data:`StartForm` (not None).
        map_name: the map's name (the key of an INI start file).
        n: team size (>= 1).
        pgraph: the map's :class:`~patrolling_sim.model.graph.PatrolGraph`.
        occupancy: the map's occupancy grid, or None (then no cell is checked).
        seed: the run's seed (``random``).
        map_dir: the map's folder (a relative start file's base).

    Returns:
        (positions, source): ``n`` (x, y) in metres, robot 0 first (a vertex start at its
        vertex's coordinates), and where they came from ("vertices", "file PATH",
        "random, seed S").

    Raises:
        PatrolInputError: one line naming the value (module doc).
    """
    if form.kind == VERTICES:
        check_initpos(form.text, n)
        starts, source = [Start(v, None, None) for v in form.vertices], VERTICES
    elif form.kind == FILE:
        path = start_file_path(form.path, map_dir)
        try:
            starts = read_start_file(path, map_name, n)
        except PatrolInputError as e:
            raise PatrolInputError(f"{WHAT}: {e}") from None
        source = f"file {path}"
    else:
        verts = random_start_vertices(pgraph, n, seed, usable_vertices(pgraph, occupancy))
        starts, source = [Start(v, None, None) for v in verts], f"random, seed {seed}"
    starts = _vertex_starts(starts, pgraph, form.text)
    problem = _place_problem(starts, occupancy)
    if problem is not None:
        raise PatrolInputError(f"{WHAT}: '{form.text}': {problem}")
    _warn_shared([s.vertex if s.vertex is not None else pgraph.nearest_vertex(s.x, s.y)
                  for s in starts], form.text)
    return [(s.x, s.y) for s in starts], source
