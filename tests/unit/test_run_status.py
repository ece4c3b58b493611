"""Run statuses without ROS: roslaunch death parsing, status records, empty metrics without
samples, the report's selection of complete runs, batch flags, and the one-line input
errors shared by the runner and graph mode."""
import csv
import os
import shutil
import subprocess
import sys

import pytest
import yaml

from patrolling_sim.monitor import run_status as rs
from patrolling_sim.experiment import validation
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.monitor.core import MonitorCore
from patrolling_sim.monitor.results import ResultWriter, RunInfo, parse_info_line
from patrolling_sim.runner.roslaunch_log import RoslaunchLog, describe_node

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
GRAPH_SIM = os.path.join(ROOT, "scripts", "graph_sim.py")
REPORT = os.path.join(ROOT, "scripts", "report.py")

# roslaunch's own words (roslaunch/pmon.py and nodeprocess.py, Debian's ros-roslaunch 1.15)
ROSLAUNCH_OUT = """\
process[robot_0/robot_nav-4]: started with pid [1204]
[robot_0/robot_nav-4] process has died [pid 1204, exit code -9, cmd /ws/robot_nav \
__name:=robot_nav __log:=/L/robot_0-robot_nav-4.log].
log file: /L/robot_0-robot_nav-4*.log
\x1b[31m================================================================================\
REQUIRED process [stage2d-2] has died!
process has died [pid 1190, exit code 134, cmd /ws/stage2d_node __name:=stage2d].
log file: /L/stage2d-2*.log
Initiating shutdown!
================================================================================\x1b[0m
ERROR: cannot launch node of type [move_base/move_base]: move_base
[patrol_agents-7] process has finished cleanly
log file: /L/patrol_agents-7*.log
"""


def test_roslaunch_deaths_are_parsed(tmp_path):
    path = tmp_path / "roslaunch.log"
    path.write_text(ROSLAUNCH_OUT[:80])          # a partial line first
    rl = RoslaunchLog(str(path))
    assert rl.poll() == []
    path.write_text(ROSLAUNCH_OUT)
    deaths = rl.poll()
    assert [(d["node"], d["exit_code"], d["required"], d["launch_error"]) for d in deaths] == [
        ("robot_0/robot_nav-4", -9, False, False), ("stage2d-2", 134, True, False),
        ("move_base/move_base", None, False, True), ("patrol_agents-7", 0, False, False)]
    assert deaths[0]["log"] == "/L/robot_0-robot_nav-4*.log"
    assert deaths[1]["log"] == "/L/stage2d-2*.log"
    assert describe_node("robot_0/robot_nav-4") == ("robot 0's navigation (robot_0/robot_nav)", 0)
    assert describe_node("patrol_robot3-12") == ("robot 3's agent (patrol_robot3)", 3)
    assert describe_node("master")[0] == "the ROS master (rosmaster)"
    assert describe_node("stage2d-2")[0] == "the simulator (stage2d)"


def test_status_words_and_exit_codes(tmp_path):
    assert rs.normalise("ABORT") == rs.ABORTED and rs.normalise(" timeout") == rs.TIMEOUT
    assert [rs.exit_code_for(s) for s in (rs.TIMEOUT, rs.CYCLES, rs.FAIL, rs.ABORTED,
                                          rs.CRASHED)] == [0, 0, 1, 1, 3]
    assert rs.exit_code_for(rs.INTERRUPTED, "SIGTERM") == 143
    assert rs.exit_code_for(rs.INTERRUPTED, "SIGINT") == 130
    prefix = str(tmp_path / "run")
    rs.write_run_yaml(prefix, {"status": rs.CRASHED, "culprit": {"node": "stage2d"}})
    rec = rs.read_run_yaml(prefix)
    assert rec["status"] == "CRASHED" and rec["complete"] is False
    log = tmp_path / "node-3-stdout.log"
    log.write_text("".join(f"line {i}\n" for i in range(30)))
    assert rs.log_tail(str(tmp_path / "node-3*.log"), 3) == ["line 27", "line 28", "line 29"]


def test_no_sample_gives_empty_metrics_and_status_is_rewritten(tmp_path):
    core = MonitorCore(4, 2)
    core.robot_ready(0)
    core.robot_ready(1)
    core.start(10.0)
    core.visit(0, 1, 12.0)               # first visits only: no idleness sample
    core.visit(1, 2, 13.0)
    st = core.stats(20.0)
    assert st.n_samples == 0 and st.global_avg is None and st.global_max is None
    prefix = str(tmp_path / "x")
    w = ResultWriter(prefix, RunInfo("grid", 2, alg="CR"))
    w.time_row(st)
    w.write_info(st, 1.0, rs.INTERRUPTED)
    w.close()
    line = open(prefix + "_info.csv").read()
    info = parse_info_line(line)
    assert info["idl_avg"] is None and info["idl_min"] is None and info["total_visits"] == 0
    assert line.split(";")[14:18] == ["", "", "", ""]
    assert open(prefix + "_timeresults.csv").read().splitlines()[1] == "10.0;;;;;0"
    assert rs.set_info_status(prefix, rs.CRASHED)
    assert parse_info_line(open(prefix + "_info.csv").read())["termination"] == "CRASHED"


def _run(root, alg, status, level, stamp, *, yaml_rec=True, timeout=None, sim=300.0,
         robots=None):
    prefix = os.path.join(root, "grid_2", alg, "h", stamp)
    w = ResultWriter(prefix, RunInfo("grid", 2, alg=alg, nav_module="spqrel_nav_lite",
                                     hostname="h", date=stamp))
    core = MonitorCore(25, 2)
    core.robot_ready(0)
    core.robot_ready(1)
    core.start(0.0)
    t = 0.0
    for k in range(3):
        for v in range(25):
            t += level / 25
            r = core.visit(k % 2, v, t)
            if r.idleness is not None:
                w.idleness_row(t, k % 2, v, r.idleness, 0)
    st = core.stats(sim)
    w.write_info(st, sim / 5, status)
    w.close()
    if yaml_rec:
        rs.write_run_yaml(prefix, {"status": status, "reason": f"test {status}",
                                   "robots": robots or [], "written_by": "runner"})
    if timeout is not None:
        with open(prefix + "_config.yaml", "w") as f:
            yaml.safe_dump({"timeout": timeout}, f)
    return prefix


def test_report_averages_only_complete_runs(tmp_path):
    root = str(tmp_path / "res")
    _run(root, "CR", "TIMEOUT", 50.0, "20260101_100001")
    _run(root, "CR", "TIMEOUT", 70.0, "20260101_100002")
    _run(root, "CR", "INTERRUPTED", 500.0, "20260101_100003", sim=40.0)
    _run(root, "CR", "CRASHED", 900.0, "20260101_100004", sim=63.0)
    _run(root, "CR", "FAIL", 300.0, "20260101_100005", robots=[1])
    # an older run (no _run.yaml) whose info.csv claims TIMEOUT at 63 of 900 s
    _run(root, "CR", "TIMEOUT", 800.0, "20260101_100006", yaml_rec=False, timeout=900.0,
         sim=63.0)
    # an older run that really reached its timeout
    _run(root, "CR", "TIMEOUT", 60.0, "20260101_100007", yaml_rec=False, timeout=300.0)
    out = str(tmp_path / "out")
    r = subprocess.run([sys.executable, REPORT, root, "--out", out, "--no-run-plots"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    summ = list(csv.DictReader(open(os.path.join(out, "summary.csv"))))
    assert len(summ) == 1 and summ[0]["runs"] == "3", summ
    # the three complete runs: levels 50, 70, 60 -> their sample means, nothing else
    assert float(summ[0]["avg_idleness_mean"]) == pytest.approx(60.0, abs=0.2)
    assert summ[0]["statuses"] == "CRASHED 1, FAIL 1, INTERRUPTED 2, TIMEOUT 3"
    excl = {e["run_id"].split("/")[-1]: e for e in
            csv.DictReader(open(os.path.join(out, "excluded.csv")))}
    assert sorted(excl) == ["20260101_100003", "20260101_100004", "20260101_100005",
                            "20260101_100006"]
    assert "63.0 of 900 sim s" in excl["20260101_100006"]["why"]
    assert "--include-fail" in excl["20260101_100005"]["why"]
    assert r.stderr.count("excluded: ") == 4
    page = open(os.path.join(out, "report.html"), encoding="utf-8").read()
    assert "Excluded runs" in page and "CRASHED" in page
    r = subprocess.run([sys.executable, REPORT, root, "--out", out, "--no-run-plots",
                        "--include-fail"], capture_output=True, text=True, timeout=300)
    summ = list(csv.DictReader(open(os.path.join(out, "summary.csv"))))
    assert r.returncode == 0 and summ[0]["runs"] == "4"
    only_bad = str(tmp_path / "bad")
    _run(only_bad, "CR", "CRASHED", 50.0, "20260101_100001")
    r = subprocess.run([sys.executable, REPORT, only_bad, "--out", out],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "no complete run" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def _one_line(cmd, needle, code=2):
    r = subprocess.run([sys.executable, *cmd], capture_output=True, text=True, timeout=120)
    lines = [ln for ln in r.stderr.strip().splitlines() if not ln.startswith("warning")]
    assert r.returncode == code, (cmd, r.stderr)
    assert len(lines) == 1 and needle in lines[0], (cmd, r.stderr)
    return r


@pytest.mark.parametrize("args,needle", [
    (["--map", "nosuch"], "argument --map: unknown map 'nosuch'"),
    (["--map", "/nonexistent/m.yaml"], "argument --map: '/nonexistent/m.yaml': file"),
    (["--robots", "0"], "argument --robots: team size must be >= 1"),
    (["--alg", "NOPE"], "argument --alg: unknown algorithm 'NOPE'"),
    (["--initpos", "zz"], "zz"),
    (["--results-dir", "/proc/forbidden"], "argument --results-dir: '/proc/forbidden' is not "
                                           "writable"),
])
def test_bad_input_one_line_in_runner_and_graph_mode(tmp_path, args, needle):
    """The same input errors, one line, non-zero, nothing written, in both modes."""
    common = {"--map": "grid", "--robots": "2", "--alg": "CR", "--results-dir": str(tmp_path)}
    common.update(dict(zip(args[::2], args[1::2])))
    flat = [x for kv in common.items() for x in kv]
    _one_line([START, *flat, "--dry-run"], needle)
    _one_line([GRAPH_SIM, *flat, "--duration", "10"], needle)
    assert not [f for _, _, fs in os.walk(tmp_path) for f in fs], "something was written"


def test_team_larger_than_graph_warns_and_nav_ros_fails_at_once(tmp_path):
    r = subprocess.run([sys.executable, GRAPH_SIM, "--map", "1r5", "--robots", "14",
                        "--duration", "5", "--results-dir", str(tmp_path), "--quiet"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "14 robots on '1r5' with 12 vertices" in r.stderr
    if shutil.which("rospack") and subprocess.run(["rospack", "find", "move_base"],
                                                  capture_output=True).returncode == 0:
        pytest.skip("move_base is installed here")
    _one_line([START, "--map", "grid", "--robots", "2", "--alg", "CR", "--nav", "ros",
               "--loc", "fake_localization", "--results-dir", str(tmp_path), "--dry-run"],
              "argument --nav: 'ros' needs the ROS packages move_base")


def test_memory_estimate_uses_the_measured_table(tmp_path):
    _one_line([START, "--map", "grid", "--robots", "500", "--alg", "CR", "--results-dir",
               str(tmp_path), "--dry-run"], "500 robots need about")
    # the same team fits on grid and not on broughton, whose planner grid is 7 times larger
    grid = validation.map_memory_figures("grid")
    broughton = validation.map_memory_figures("broughton")
    assert validation.check_memory(20, "shared", *grid, available=4000.0) < 4000
    with pytest.raises(PatrolInputError, match="20 robots need about .* on this map .*"
                                               "give --force"):
        validation.check_memory(20, "shared", *broughton, available=4000.0)
    assert validation.check_memory(20, "shared", *broughton, force=True, available=4000.0) \
        > 4000


def test_batch_flags_reach_every_run(tmp_path):
    batch = tmp_path / "b.yaml"
    batch.write_text("base: {map: grid, loc: fake_localization, timeout: 300}\n"
                     "grid: {alg: [CR, CGG], robots: [1, 2]}\n")
    r = subprocess.run([sys.executable, START, "--batch", str(batch), "--results-dir",
                        str(tmp_path / "X"), "--speedup", "2", "--timeout", "10",
                        "--dead-robot-timeout", "60", "--dry-run"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    runs = [ln for ln in r.stdout.splitlines() if ln.startswith("run ")]
    assert len(runs) == 4
    for ln in runs:
        assert f"results_dir={tmp_path / 'X'}" in ln and " speedup=2.0 " in ln
        assert " timeout=10.0 " in ln and " dead_robot_timeout=60.0 " in ln
    assert {ln.split(" alg=")[1].split()[0] for ln in runs} == {"CR", "CGG"}


def test_user_map_results_never_collide_with_a_shipped_map(tmp_path):
    from patrolling_sim.common import paths
    src = os.path.join(paths.maps_dir(), "grid")
    mine = tmp_path / "grid"
    shutil.copytree(src, mine)
    assert validation.result_map_name("grid") == "grid"
    name = validation.result_map_name(str(mine / "grid.yaml"))
    assert name.startswith("grid-") and len(name) == len("grid-") + 8
    with open(mine / "grid.graph", "a") as f:
        f.write("\n")
    assert validation.result_map_name(str(mine / "grid.yaml")) != name
    r = subprocess.run([sys.executable, START, "--map", str(mine / "grid.yaml"), "--robots",
                        "2", "--alg", "CR", "--results-dir", str(tmp_path / "r"), "--dry-run"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert os.path.isdir(
        tmp_path / "r" / f"{validation.result_map_name(str(mine / 'grid.yaml'))}_2")


def test_a_long_silence_is_named_when_the_run_did_not_fail():
    from patrolling_sim.monitor.run_status import silence_warning
    # robot 1 silent 230 s of a 300 s dead-robot time: named; 150 s (half) is not; robot 2
    # beyond 300 s is a FAIL, named by the status instead
    line = silence_warning([40.0, 230.4, 150.0], 300.0)
    assert "robot 1 230 s" in line and "robot 2" not in line and "robot 0" not in line
    assert silence_warning([40.0, 150.0, 301.0], 300.0) is None
    assert silence_warning([400.0], 0.0) is None              # no dead-robot rule
    assert silence_warning([], 300.0) is None                  # before GO / no record
