"""Resolve a run's ``initpos`` setting to start positions, whatever its form."""
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.startpos.explicit import parse_initpos
from patrolling_sim.startpos.explicit import stated_start_positions
from patrolling_sim.startpos.initial_poses import OPTIMISED, table_positions
from patrolling_sim.startpos.optimised import optimised_start_positions


def start_positions(map_name, n, pgraph, occupancy, initpos="default", table=None,
                    table_path=None, alg=None, seed=0, map_dir=None):
    """Start positions for ``n`` robots on ``map_name``.

    Args:
        map_name: the map's name (the table's key prefix).
        n: team size (>= 1).
        pgraph: the map's :class:`~patrolling_sim.model.graph.PatrolGraph`.
        occupancy: the map's occupancy grid (``spqrel_nav_lite.mapio.OccupancyMap``), or None.
        initpos: "default", a variant name of the original's table, "optimised" (start
            vertices chosen for the algorithm ``alg``,
            :func:`patrolling_sim.startpos.optimised.optimised_start_positions`), or one
            of the stated or random forms of :mod:`patrolling_sim.startpos.explicit`
            (a vertex list, a start file, "random").
        table, table_path: the parsed ``initial_poses.txt`` and its path (for messages).
        alg: the algorithm's short name (needed by "optimised").
        seed: the run's seed (needed by "random").
        map_dir: the map's folder, against which a relative start file is resolved.

    Returns:
        (positions, source): a list of ``n`` (x, y) and where they came from: "table",
        "computed", "optimised for ALG: <method>", "vertices", "file PATH" or
        "random, seed S".

    Raises:
        PatrolInputError: a bad team size or variant (see
            :func:`~patrolling_sim.startpos.initial_poses.table_positions`), or a stated
            start that is malformed or cannot be used (see
            :func:`~patrolling_sim.startpos.explicit.stated_start_positions`).
    """
    if n < 1:
        raise PatrolInputError(f"team size must be >= 1, got {n}")
    form = parse_initpos(initpos)
    if form is not None:
        return stated_start_positions(form, map_name, n, pgraph, occupancy, seed, map_dir)
    if initpos == OPTIMISED:
        default, _ = table_positions(map_name, n, pgraph, occupancy, "default", table,
                                     table_path)
        return optimised_start_positions(pgraph, occupancy, n, alg, map_name, default)
    return table_positions(map_name, n, pgraph, occupancy, initpos, table, table_path)
