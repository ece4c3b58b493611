"""Parameters and message helpers of the PatrolAgent node (:mod:`patrolling_sim.ros.agent`):
robot frame ids on ``/positions``, int16 clamping of ``/results`` payloads, the start vertex
from ``/initial_pos``, private and global parameters read with one-line errors."""
import math
import re

import rospy

from patrolling_sim import algorithms
from patrolling_sim.common.protocol import INT16_MAX

INT16_MIN = -32768
_ROBOT_FRAME = re.compile(r"robot_(\d+)(?:/|$)")


class AgentError(Exception):
    """Fatal start-up problem; ``str()`` is one line, the node exits with ``code``."""

    def __init__(self, message, code=2):
        super().__init__(message)
        self.code = code


def parse_robot_frame(frame_id):
    """Robot index from a ``/positions`` frame id ``robot_<i>/map`` (None if absent)."""
    m = _ROBOT_FRAME.search(frame_id or "")
    return int(m.group(1)) if m else None


def clamp_int16(data):
    """(clamped list, True if any value had to be clamped)."""
    out, clamped = [], False
    for x in data:
        x = int(x)
        if x > INT16_MAX:
            x, clamped = INT16_MAX, True
        elif x < INT16_MIN:
            x, clamped = INT16_MIN, True
        out.append(x)
    return out, clamped


def start_vertex_from(graph, initial_pos, robot_id):
    """Start vertex of ``robot_id`` from the flat ``/initial_pos`` list (x0,y0,x1,y1,...)."""
    try:
        flat = [float(x) for x in initial_pos]
    except (TypeError, ValueError):
        raise AgentError(f"/initial_pos: expected a flat list of numbers, got {initial_pos!r}")
    if len(flat) < 2 * (robot_id + 1):
        raise AgentError(f"/initial_pos has {len(flat) // 2} positions, robot {robot_id} "
                         f"needs at least {robot_id + 1}")
    x, y = flat[2 * robot_id], flat[2 * robot_id + 1]
    return graph.nearest_vertex(x, y), (x, y)


def float_param(name, default, minimum=None):
    """ROS parameter ``name`` as a float (>= ``minimum``); AgentError if it is not."""
    raw = rospy.get_param(name, default)
    try:
        val = float(raw)
    except (TypeError, ValueError):
        raise AgentError(f"{name}: expected a number, got {raw!r}")
    if minimum is not None and (val < minimum or math.isnan(val)):
        raise AgentError(f"{name} must be >= {minimum}, got {raw!r}")
    return val


def optional_int_param(name):
    """Private parameter ``name`` as an int, None if unset; AgentError if not an integer."""
    value = rospy.get_param(name, None)
    if value is None:
        return None
    try:
        return int(value)
    except (TypeError, ValueError):
        raise AgentError(f"{name}: expected an integer, got {value!r}") from None


def read_common_params():
    """(algorithm, team_size, seed, params) from the node's private parameters."""
    if not rospy.has_param("~algorithm"):
        known = ", ".join(algorithms.names())
        raise AgentError(f"~algorithm is required (known: {known})")
    alg = str(rospy.get_param("~algorithm"))
    team_size = optional_int_param("~team_size")
    seed = optional_int_param("~seed")
    params = rospy.get_param("~params", {})
    if not isinstance(params, dict):
        raise AgentError(f"~params: expected a dictionary, got {params!r}")
    return alg, team_size, seed, params


def parse_ids(tokens):
    """Robot ids from ``['0', '2', '5-7']`` -> [0, 2, 5, 6, 7] (sorted, no duplicates)."""
    ids = set()
    for tok in tokens:
        m = re.fullmatch(r"(\d+)(?:-(\d+))?", tok)
        if not m:
            raise AgentError(f"robot id: expected an integer or a range a-b, got '{tok}'")
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        if b < a:
            raise AgentError(f"robot id range '{tok}' is empty")
        ids.update(range(a, b + 1))
    return sorted(ids)
