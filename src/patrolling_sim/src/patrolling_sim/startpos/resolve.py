"""Resolve a run's ``initpos`` setting to start positions, whatever its form."""
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.startpos.initial_poses import OPTIMISED, table_positions
from patrolling_sim.startpos.optimised import optimised_start_positions


def start_positions(map_name, n, pgraph, occupancy, initpos="default", table=None,
                    table_path=None, alg=None):
    """Start positions for ``n`` robots on ``map_name``.

    Args:
        map_name: the map's name (the table's key prefix).
        n: team size (>= 1).
        pgraph: the map's :class:`~patrolling_sim.model.graph.PatrolGraph`.
        occupancy: the map's occupancy grid (``spqrel_nav_lite.mapio.OccupancyMap``), or None.
        initpos: "default", a variant name of the original's table, or "optimised" (start
            vertices chosen for the algorithm ``alg``,
            :func:`patrolling_sim.startpos.optimised.optimised_start_positions`).
        table, table_path: the parsed ``initial_poses.txt`` and its path (for messages).
        alg: the algorithm's short name (needed by "optimised").

    Returns:
        (positions, source): a list of ``n`` (x, y) and where they came from: "table",
        "computed", or "optimised for ALG: <method>".

    Raises:
        PatrolInputError: a bad team size or variant (see
        :func:`~patrolling_sim.startpos.initial_poses.table_positions`).
    """
    if n < 1:
        raise PatrolInputError(f"team size must be >= 1, got {n}")
    if initpos == OPTIMISED:
        default, _ = table_positions(map_name, n, pgraph, occupancy, "default", table,
                                     table_path)
        return optimised_start_positions(pgraph, occupancy, n, alg, map_name, default)
    return table_positions(map_name, n, pgraph, occupancy, initpos, table, table_path)
