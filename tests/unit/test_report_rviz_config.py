"""scripts/make_rviz_config.py and patrolling_sim.report.rviz_config (no rviz needed)."""
import os
import subprocess
import sys

import pytest
import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
GEN = os.path.join(ROOT, "scripts", "make_rviz_config.py")


def gen(*args):
    return subprocess.run([sys.executable, GEN, *args], capture_output=True, text=True,
                          timeout=60)


def displays_by_class(cfg):
    out = {}

    def walk(ds):
        for d in ds:
            out.setdefault(d["Class"], []).append(d)
            walk(d.get("Displays", []))
    walk(cfg["Visualization Manager"]["Displays"])
    return out


def test_structure_for_six_robots_on_example():
    p = gen("--robots", "6", "--enabled", "2", "--map", "example")
    assert p.returncode == 0, p.stderr
    cfg = yaml.safe_load(p.stdout)
    vm = cfg["Visualization Manager"]
    assert vm["Global Options"]["Fixed Frame"] == "map"
    by = displays_by_class(cfg)
    groups = by["rviz/Group"]
    assert [g["Name"] for g in groups] == [f"robot_{i}" for i in range(6)]
    assert [g["Enabled"] for g in groups] == [True, True, False, False, False, False]
    assert [d["Topic"] for d in by["rviz/Map"]] == ["/map"]
    assert [d["Marker Topic"] for d in by["rviz/MarkerArray"]] == ["/patrol_graph_markers"]
    for cls, suffix in (("rviz/PoseWithCovariance", "amcl_pose"),
                        ("rviz/LaserScan", "base_scan"),
                        ("rviz/PoseArray", "particlecloud"),
                        ("rviz/Path", "move_base/plan")):
        assert [d["Topic"] for d in by[cls]] == [f"/robot_{i}/{suffix}" for i in range(6)]
    # view centred on example's extent: 313 x 219 px at 0.15 m, origin (0, 0)
    view = vm["Views"]["Current"]
    assert view["Class"] == "rviz/TopDownOrtho"
    assert view["X"] == pytest.approx(313 * 0.15 / 2, abs=1e-3)
    assert view["Y"] == pytest.approx(219 * 0.15 / 2, abs=1e-3)
    # the whole map fits the render area (window minus docks)
    assert view["Scale"] * 313 * 0.15 <= cfg["Window Geometry"]["Width"] - 600


def test_view_follows_map_origin():
    # move_base_arena's yaml origin is (-5.375, -5.25): the centre moves with it
    from patrolling_sim.common import paths
    from spqrel_nav_lite.mapio import load_map
    occ = load_map(paths.map_files("move_base_arena")[0])
    cfg = yaml.safe_load(gen("--map", "move_base_arena").stdout)
    view = cfg["Visualization Manager"]["Views"]["Current"]
    w, h = occ.size_m
    assert view["X"] == pytest.approx(occ.origin[0] + w / 2, abs=1e-3)
    assert view["Y"] == pytest.approx(occ.origin[1] + h / 2, abs=1e-3)


def test_writes_file(tmp_path):
    out = tmp_path / "x.rviz"
    p = gen("--robots", "1", "--out", str(out))
    assert p.returncode == 0 and p.stdout == ""
    cfg = yaml.safe_load(out.read_text())
    assert len(displays_by_class(cfg)["rviz/Group"]) == 1


@pytest.mark.parametrize("args,needle", [
    (["--robots", "0"], "argument --robots: 0 is below 1"),
    (["--robots", "two"], "argument --robots: 'two' is not an integer"),
    (["--robots", "2", "--enabled", "3"], "argument --enabled: 3 exceeds --robots 2"),
    (["--map", "nosuchmap"], "unknown map 'nosuchmap'"),
    (["--out", "/nonexistent_dir_xyz/a.rviz"], "argument --out: cannot write"),
])
def test_bad_arguments(args, needle):
    p = gen(*args)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("make_rviz_config.py: error: ")
    assert needle in lines[0], lines[0]


def test_experiment_config_for_runner():
    from patrolling_sim.report.rviz_config import experiment_config_text
    from patrolling_sim.common.errors import PatrolInputError
    cfg = yaml.safe_load(experiment_config_text(3, "cumberland"))
    groups = displays_by_class(cfg)["rviz/Group"]
    assert [g["Enabled"] for g in groups] == [True, True, True]
    view = cfg["Visualization Manager"]["Views"]["Current"]
    assert view["X"] == pytest.approx(688 * 0.075 / 2, abs=1e-3)
    with pytest.raises(PatrolInputError):
        experiment_config_text(2, "nosuchmap")
