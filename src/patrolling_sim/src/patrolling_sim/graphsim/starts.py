"""Where the robots of a graph-mode run start (:mod:`patrolling_sim.graphsim.simulator`)."""
import os

from patrolling_sim.common import paths
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.startpos.initial_poses import load_initial_poses
from patrolling_sim.startpos.resolve import start_positions
from spqrel_nav_lite.mapio import load_map


def start_vertices_of(cfg: GraphSimConfig, pgraph: PatrolGraph):
    """The start vertex of each robot of ``cfg`` on ``pgraph``: the vertices nearest to the
    start positions of ``cfg.initpos`` (the map's table, computed, optimised, stated
    vertices or poses, or random from ``cfg.seed``; docs/protocol.md). Raises
    PatrolInputError when they cannot be placed."""
    yaml_path, _ = paths.map_files(cfg.map)
    occ = load_map(yaml_path)
    table_path = paths.initial_poses_file()
    pos, _ = start_positions(paths.map_name(cfg.map), cfg.robots, pgraph, occ, cfg.initpos,
                             load_initial_poses(table_path), table_path, alg=cfg.alg,
                             seed=cfg.seed, map_dir=os.path.dirname(os.path.abspath(yaml_path)))
    return [pgraph.nearest_vertex(x, y) for x, y in pos]
