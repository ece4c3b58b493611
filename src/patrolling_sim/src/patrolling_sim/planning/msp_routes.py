"""MSP route files: ``MSP/<map>/<map>_<N>_<i>``.

Format: the first integer L, then L vertex ids (whitespace separated, usually one per
line). A valid route is a closed walk on the current graph: every id exists, consecutive
ids are adjacent, the first equals the last, and exactly L ids follow the header.
Most shipped files (example, cumberland) predate the current graphs and are *stale*;
:func:`load_route` detects that and says why.
"""
from patrolling_sim.common.errors import PatrolInputError, StaleRouteError
from patrolling_sim.common.textfile import read_text


def parse_route(text, path="<route>"):
    toks = text.split()
    if not toks:
        raise PatrolInputError(f"{path}: empty MSP route file")
    vals = []
    for k, t in enumerate(toks):
        try:
            vals.append(int(t))
        except ValueError:
            raise PatrolInputError(f"{path}: token {k + 1} must be an integer vertex id, "
                                   f"got '{t}'") from None
    return vals[0], vals[1:]


def validate_route(length, route, pgraph, path="<route>"):
    """Raise StaleRouteError unless ``route`` is a closed walk on ``pgraph`` of ``length``."""
    if length != len(route):
        raise StaleRouteError(f"{path}: header says {length} vertices but {len(route)} follow "
                              f"(stale route file)")
    if len(route) < 2:
        raise StaleRouteError(f"{path}: route needs at least 2 entries, got {len(route)}")
    bad = [v for v in route if not 0 <= v < pgraph.n]
    if bad:
        raise StaleRouteError(f"{path}: vertex {bad[0]} does not exist in graph "
                              f"'{pgraph.name}' (0..{pgraph.n - 1}); stale route file")
    for a, b in zip(route, route[1:]):
        if a != b and pgraph.arc_cost(a, b) is None:
            raise StaleRouteError(f"{path}: consecutive vertices {a} and {b} are not adjacent "
                                  f"in graph '{pgraph.name}'; stale route file")
    if route[0] != route[-1]:
        raise StaleRouteError(f"{path}: route is not closed (starts at {route[0]}, ends at "
                              f"{route[-1]})")


def load_route(path, pgraph):
    """Read and validate a route file. Returns the list of vertex ids (closed walk)."""
    length, route = parse_route(read_text(path, "MSP route file"), path)
    validate_route(length, route, pgraph, path)
    return route


def format_route(route):
    return "\n".join([str(len(route))] + [str(v) for v in route]) + "\n"
