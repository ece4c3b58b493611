"""The supervisor's named steps without ROS: the one prefix claim (results.claim_prefix,
used by the runner and graph mode), the outcome decision (runner/outcome.py) and the
late-death scan after roslaunch ended."""
import os
import types

import yaml

from patrolling_sim.monitor import run_status as rs
from patrolling_sim.monitor.results import claim_prefix, hostname
from patrolling_sim.runner import outcome
from patrolling_sim.runner.config import ExperimentConfig
from patrolling_sim.runner.supervisor import claim_prefix as runner_claim


def death(node, code, required=False, launch_error=False):
    return {"node": node, "exit_code": code, "log": None, "required": required,
            "launch_error": launch_error}


def test_claim_prefix_marker_and_content(tmp_path):
    p = str(tmp_path / "a" / "b" / "20250101_000000")
    assert claim_prefix(p) == p
    assert os.path.getsize(p + "_idleness.csv") == 0
    assert claim_prefix(p) == p + "_1"
    assert claim_prefix(p, "_config.yaml", "x: 1\n") == p     # another marker: free
    with open(p + "_config.yaml", encoding="utf-8") as f:
        assert f.read() == "x: 1\n"
    assert claim_prefix(p, "_config.yaml", "x: 2\n") == p + "_1"


def test_runner_claim_uses_host_folder_and_writes_config(tmp_path):
    cfg = ExperimentConfig(map="grid", robots=4, alg="CGG", loc="fake_localization",
                           timeout=300.0, results_dir=str(tmp_path))
    p1 = runner_claim(cfg, stamp="20250101_000000")
    p2 = runner_claim(cfg, stamp="20250101_000000")
    assert p1 == os.path.join(str(tmp_path), f"{cfg.result_name}_4", "CGG", hostname(),
                              "20250101_000000")
    assert p2 == p1 + "_1"
    with open(p1 + "_config.yaml", encoding="utf-8") as f:
        assert yaml.safe_load(f)["alg"] == "CGG"


def test_decide_status_first_cause_first():
    info = ["x"] * 13 + ["TIMEOUT"]
    crash = death("robot_1/robot_nav-5", -9)
    d = outcome.decide_status
    assert d("SIGTERM", crash, "why", info, {})["status"] == rs.INTERRUPTED
    assert d("GUI stop", crash, "why", info, {})["reason"] == "GUI stop"
    r = d(None, crash, "why", info, {})
    assert r["status"] == rs.CRASHED and r["culprit"]["robot"] == 1
    assert r["reason"] == "robot 1's navigation (robot_1/robot_nav) died (exit -9)"
    assert d(None, None, "why", info, {})["status"] == rs.ABORTED
    assert d(None, None, None, None, {})["culprit"]["node"] == "monitor"
    r = d(None, None, None, ["x"] * 13 + ["FAIL"], {"reason": "r", "robots": [2]})
    assert (r["status"], r["robots"]) == (rs.FAIL, [2])
    r = d(None, None, None, ["x"] * 13 + ["INTERRUPTED"], {})
    assert r["culprit"]["node"] == "roslaunch"
    assert outcome.summary(rs.FAIL, {"reason": "x", "robots": [2]}, 60) == \
        "FAIL: robot(s) 2 sent no visit for 60 sim s"


def test_late_crash_rules():
    nav = death("robot_0/robot_nav-5", 1)
    mon_ok, mon_bad = death("monitor-3", 0), death("monitor-3", 2)
    assert outcome.late_crash([mon_ok, nav], ended=False) is nav
    assert outcome.late_crash([mon_ok, nav], ended=True) is None
    assert outcome.late_crash([nav, mon_bad], ended=True) is mon_bad
    assert outcome.late_crash([death("x", None, launch_error=True)], True)["node"] == "x"


def test_timing_prefers_monitor_figures():
    info = ["x"] * 10 + ["120.0", "60.0"]
    assert outcome.timing(info, None, 5.0, 100.0) == (120.0, 60.0, 2.0)
    w = types.SimpleNamespace(sim_time=50.0, sim_at_go=10.0)
    assert outcome.timing(None, w, 5.0, 25.0) == (40.0, 20.0, 2.0)
    assert outcome.timing(None, None, None, 25.0) == (None, None, None)
