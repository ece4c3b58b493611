"""MSP route files, DTA params and the graph_tool command line."""
import os
import subprocess
import sys

import pytest

from patrolling_sim.common import paths
from patrolling_sim.model.dta_params import load_dta_params
from patrolling_sim.common.errors import PatrolInputError, StaleRouteError
from patrolling_sim.model.graph import PatrolGraph, load_graph
from patrolling_sim.planning.msp_routes import format_route, load_route

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def pg(name):
    return PatrolGraph(load_graph(paths.map_files(name)[1]))


def test_grid_msp_routes_valid():
    g = pg("grid")
    for n in range(1, 10):
        covered = set()
        for i in range(n):
            r = load_route(paths.msp_route_file("grid", n, i), g)
            assert r[0] == r[-1]
            covered |= set(r)
        assert covered == set(range(25))


@pytest.mark.parametrize("name,n", [("example", 2), ("cumberland", 4)])
def test_stale_routes_detected(name, n):
    g = pg(name)
    with pytest.raises(StaleRouteError, match="stale route file"):
        for i in range(n):
            load_route(paths.msp_route_file(name, n, i), g)


def test_route_errors(tmp_path):
    g = pg("grid")
    f = tmp_path / "r"
    f.write_text(format_route([0, 1, 2, 1, 0]))
    assert load_route(str(f), g) == [0, 1, 2, 1, 0]
    f.write_text("3\n0\n1\n")
    with pytest.raises(StaleRouteError, match="header says 3"):
        load_route(str(f), g)
    f.write_text("3\n0\n2\n0\n")
    with pytest.raises(StaleRouteError, match="not adjacent"):
        load_route(str(f), g)
    f.write_text("2\n0\nx\n")
    with pytest.raises(PatrolInputError, match="integer vertex id"):
        load_route(str(f), g)
    with pytest.raises(PatrolInputError, match="not found"):
        load_route(str(tmp_path / "none"), g)


def test_dta_params():
    p = load_dta_params(paths.dta_params_file("DTAGreedy"))
    assert p == {"theta_idleness": 1.0, "theta_navigation": -0.75,
                 "theta_distance_from_origin": -5.0}
    q = load_dta_params(paths.dta_params_file("DTASSI"))
    assert q["timeout"] == 3.0 and q["theta_hop"] == -2.0 and q["hist"] == 0.0


def test_dta_params_errors(tmp_path):
    f = tmp_path / "x.params"
    f.write_text("[SECTION Main]\nPROFILE p\n[END]\n")
    with pytest.raises(PatrolInputError, match="profile 'p' is not defined"):
        load_dta_params(str(f))
    f.write_text("[PROFILE p]\nkey\n[END]\n")
    with pytest.raises(PatrolInputError, match=r"x.params:2: expected 'key value'"):
        load_dta_params(str(f))


def _tool(*args):
    return subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_tool.py"),
                           *args], capture_output=True, text=True)


def test_cli_check_all_maps():
    r = _tool("check")
    assert r.returncode == 0, r.stderr
    assert "grid: V=25 E=40" in r.stdout and "broughton: V=163 E=186" in r.stdout


@pytest.mark.parametrize("args,needle", [
    (("check", "nosuchmap"), "unknown map 'nosuchmap'"),
    (("startposes", "grid", "0"), "team size must be >= 1"),
    (("startposes", "grid", "x"), "invalid int value: 'x'"),
    (("startposes", "1r5", "4", "--initpos", "q"), "no entry '1r5_4_q'"),
    (("bogus",), "invalid choice: 'bogus'"),
])
def test_cli_errors_one_line(args, needle):
    r = _tool(*args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr


def test_cli_bad_graph_file(tmp_path):
    (tmp_path / "m.graph").write_text("2 10 10 0.1 0 0\n0 1 1 1 5 E 3\n")
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    r = _tool("write", str(tmp_path / "m.graph"), "--out", str(tmp_path / "o.graph"))
    assert r.returncode == 2 and "out of range" in r.stderr
    assert not (tmp_path / "o.graph").exists()          # nothing half-written


def test_cli_startposes_and_draw(tmp_path):
    r = _tool("startposes", "cumberland", "40")
    assert r.returncode == 0 and r.stdout.count("robot_") == 40
    out = tmp_path / "g.png"
    assert _tool("draw", "1r5", "--out", str(out)).returncode == 0 and out.stat().st_size > 1000
