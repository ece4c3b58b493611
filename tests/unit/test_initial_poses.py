"""Start positions: table parsing, variants, computed spreads for N = 1..32 on every map."""

import numpy as np
import pytest

from patrolling_sim.common import paths
from patrolling_sim.model import map_bundle
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.model.graph import PatrolGraph
from patrolling_sim.startpos.initial_poses import (check_start_positions,
                                                   compute_start_positions,
                                                   load_initial_poses, spread_vertices)
from patrolling_sim.startpos.resolve import start_positions

TABLE = load_initial_poses(paths.initial_poses_file())
BUNDLES = {}


def bundle(name):
    if name not in BUNDLES:
        occ, G = map_bundle.load_map_bundle(name)
        BUNDLES[name] = (occ, PatrolGraph(G))
    return BUNDLES[name]


def test_table_parsing():
    assert TABLE["grid_1"] == [(1.425, 24.375)]
    assert len(TABLE["cumberland_4_c"]) == 4
    assert TABLE["move_base_arena_3"][0] == (-4.0, -4.0)


def test_variant_lookup():
    occ, pg = bundle("cumberland")
    pos, src = start_positions("cumberland", 4, pg, occ, "b", TABLE)
    assert src == "table" and pos[0] == (3.0, 12.0)
    with pytest.raises(PatrolInputError, match="no entry 'cumberland_4_z'"):
        start_positions("cumberland", 4, pg, occ, "z", TABLE)


@pytest.mark.parametrize("name", paths.available_maps())
def test_every_team_size_valid_and_deterministic(name):
    occ, pg = bundle(name)
    for n in range(1, 33):
        pos, src = start_positions(name, n, pg, occ, "default", TABLE)
        assert len(pos) == n
        assert check_start_positions(pos, occ) is None
        p = np.array(pos)
        d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
        np.fill_diagonal(d, np.inf)
        assert d.min() >= 0.5
        if src == "computed" and n <= pg.n:
            verts = {pg.nearest_vertex(x, y) for x, y in pos}
            assert len(verts) == n                      # distinct vertices while N <= V
        assert start_positions(name, n, pg, occ, "default", TABLE) == (pos, src)


def test_spread_is_farthest_point():
    occ, pg = bundle("grid")
    v = spread_vertices(pg, 5)
    assert v[0] == 12                                   # centre of the 5x5 lattice
    assert set(v[1:]) == {0, 4, 20, 24}                 # then the four corners


def test_impossible_team_size():
    occ, pg = bundle("1r5")
    with pytest.raises(PatrolInputError, match="cannot hold 5000 robots"):
        compute_start_positions(pg, occ, 5000)
    with pytest.raises(PatrolInputError, match="team size must be >= 1"):
        start_positions("1r5", 0, pg, occ)


def test_invalid_table_entry_falls_back(tmp_path):
    occ, pg = bundle("grid")
    bad = {"grid_2": [(0.0, 0.0), (1.425, 24.375)]}     # (0, 0) is the wall corner
    pos, src = start_positions("grid", 2, pg, occ, "default", bad)
    assert src == "computed" and check_start_positions(pos, occ) is None


@pytest.mark.parametrize("text,needle", [
    ("[Other]\na: [1, 2]\n", "no [InitialPoses] section"),
    ("[InitialPoses]\ngrid_1: [1, 2, 3]\n", "even"),
    ("[InitialPoses]\ngrid_1: [1, x]\n", "list of numbers"),
    ("not an ini file", "malformed INI"),
])
def test_malformed_table(tmp_path, text, needle):
    p = tmp_path / "poses.txt"
    p.write_text(text)
    with pytest.raises(PatrolInputError) as ei:
        load_initial_poses(str(p))
    assert needle in str(ei.value) and str(p) in str(ei.value)
