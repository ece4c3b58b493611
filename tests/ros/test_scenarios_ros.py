"""Scenarios in ROS mode through scripts/start_experiments.py (docs/scenarios.md): a robot
failing mid-run stops where it is and goes silent, the others keep patrolling, the run ends
normally (TIMEOUT, not FAIL) with the failure recorded in ``<prefix>_scenario.yaml``; a
repaired robot patrols again; a communication model drops messages at the receivers.

(a) full stack (simulator, fake localisation, navigation), grid, SEBS, 4 robots, agents in
    one process: robot 2 fails 80 s after GO and stays silent for 240 s, more than the
    dead-robot timeout (200 s), which must not end the run; its ground-truth pose is
    followed with tests/ros/pose_probe.py on the run's master. The timeout is above the
    longest a live robot can go without a visit when its goal vertex is blocked by the
    failed robot's body (docs/scenarios.md, "a failed robot's body blocks a vertex"): four
    navigation attempts of about 30 s each, then the next vertex (a 60 s timeout ends the
    run as FAIL).
(b) abstract world, grid, DTAP, 3 robots, one process per agent, Bernoulli loss 0.2: robot
    1 fails at 80 s and is back at 180 s; its pose (odom) is followed the same way.
(c) abstract world, grid, 2 robots on opposite sides of an obstacle, range model with and
    without line of sight.
Results are judged on sim-time figures only; the wall limits only stop a hung run.
"""
import glob
import os
import re
import signal
import subprocess

import pytest
import yaml

from rosenv import ros_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
PROBE = os.path.join(os.path.dirname(__file__), "pose_probe.py")
RUN_LIMIT = 600.0           # wall s: safety net against a hung run only


def start(args, tmp_path):
    return subprocess.Popen(["/usr/bin/python3", START, "--headless", *args, "--results-dir",
                             str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=ros_env(), cwd=str(tmp_path),
                            start_new_session=True)


def finish(proc, head=""):
    try:
        out, _ = proc.communicate(timeout=RUN_LIMIT)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        pytest.fail("experiment did not end:\n" + (head + out)[-3000:])
    return proc.returncode, head + out


def results(tmp_path):
    """(prefix, run.yaml, scenario.yaml, visits [(t since GO, robot, vertex)])."""
    found = glob.glob(f"{tmp_path}/**/*_scenario.yaml", recursive=True)
    assert len(found) == 1, found
    prefix = found[0][:-len("_scenario.yaml")]
    with open(prefix + "_run.yaml") as f:
        run = yaml.safe_load(f)
    with open(prefix + "_scenario.yaml") as f:
        scen = yaml.safe_load(f)
    visits = []
    with open(prefix + "_visits.csv") as f:
        for line in f.read().splitlines()[1:]:
            t, r, v = line.split(";")
            visits.append((float(t), int(r), int(v)))
    return prefix, run, scen, visits


def on_time(recorded, scheduled):
    """A failure/repair time the monitor recorded (when the report arrived) against the
    schedule: late by the agent's timer latency times the pace (on a loaded machine at 30x a
    few sim seconds); early only by the monitor's own clock lagging the agent's: each node
    keeps the latest /clock it has received, and a loaded monitor's /clock thread can be a
    few tens of wall ms behind, i.e. up to a sim second or two at 30x (a failure due at 80 s
    after GO, sent when the agent's clock read 80.06, can be recorded at 79.0). Accepted:
    up to 2 sim s early and 6 sim s late."""
    return scheduled - 2.0 <= recorded <= scheduled + 6.0


def follow_pose(proc, robot, topic):
    """Run ``proc`` (the runner) to its end while tests/ros/pose_probe.py follows robot
    ``robot``'s pose on its master: (exit code, output, GO sim time, [(t, x, y)])."""
    head, uri = "", None
    while uri is None:
        line = proc.stdout.readline()
        if not line:
            break
        head += line
        m = re.search(r"master (http://127\.0\.0\.1:\d+)", line)
        uri = m.group(1) if m else None
    assert uri, head
    env = dict(ros_env(), ROS_MASTER_URI=uri)
    probe = subprocess.Popen(["/usr/bin/python3", PROBE, str(robot), topic],
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                             env=env)
    try:
        code, out = finish(proc, head)
    finally:
        probe.terminate()
        poses, _ = probe.communicate(timeout=30)
    lines = poses.splitlines()
    go = [float(l.split()[1]) for l in lines if l.startswith("go ")]
    assert go, poses[-2000:]
    xy = [tuple(map(float, l.split())) for l in lines
          if re.fullmatch(r"-?[0-9.]+ -?[0-9.]+ -?[0-9.]+", l)]
    return code, out, go[0], xy


def test_full_stack_sebs_failure(tmp_path):
    proc = start(["--map", "grid", "--robots", "4", "--alg", "SEBS", "--loc",
                  "fake_localization", "--timeout", "320", "--speedup", "10",
                  "--attrition", "2@80", "--dead-robot-timeout", "200"], tmp_path)
    code, out, go, xy = follow_pose(proc, 2, "base_pose_ground_truth")
    assert code == 0, out[-3000:]
    prefix, run, scen, visits = results(tmp_path)
    assert run["status"] == "TIMEOUT", run
    assert scen["mode"] == "ros" and scen["schedule"] == "2@80" and scen["comm"] == "perfect"
    [fail] = scen["failures"]
    assert fail["robot"] == 2 and fail["t_repair"] is None
    assert on_time(fail["t_fail"], 80.0), fail
    t_fail = fail["t_fail"]
    # the failed robot's visits stop; every other robot keeps visiting vertices
    mine = [t for t, r, _ in visits if r == 2]
    assert mine and max(mine) <= t_fail + 0.5, mine
    for r in (0, 1, 3):
        assert len({v for t, rr, v in visits if rr == r and t > t_fail + 5}) >= 2, r
    # it stays where it stopped (the cmd_vel watchdog and the zero twist: at most a few cm
    # of coasting within 3 s), having moved before
    before = [(x, y) for t, x, y in xy if t < go + t_fail - 1]
    after = [(x, y) for t, x, y in xy if t > go + t_fail + 3]
    assert len(after) >= 60, len(after)
    assert max(abs(x - after[0][0]) + abs(y - after[0][1]) for x, y in after) < 0.01
    assert max(abs(x - before[0][0]) + abs(y - before[0][1]) for x, y in before) > 1.0


def test_abstract_dtap_failure_and_repair_with_loss(tmp_path):
    proc = start(["--map", "grid", "--robots", "3", "--alg", "DTAP", "--nav", "abstract",
                  "--timeout", "300", "--speedup", "30", "--processes", "separate",
                  "--attrition", "1@80+100", "--comm", "bernoulli:p=0.2"], tmp_path)
    code, out, go, xy = follow_pose(proc, 1, "odom")
    assert code == 0, out[-3000:]
    prefix, run, scen, visits = results(tmp_path)
    assert run["status"] == "TIMEOUT", run
    [fail] = scen["failures"]
    assert fail["robot"] == 1 and on_time(fail["t_fail"], 80.0), fail
    assert fail["t_repair"] is not None and on_time(fail["t_repair"], 180.0), fail
    mine = [t for t, r, _ in visits if r == 1]
    assert any(t < fail["t_fail"] for t in mine)
    assert not [t for t in mine if fail["t_fail"] + 0.5 < t < fail["t_repair"]], mine
    assert len([t for t in mine if t > fail["t_repair"]]) >= 3, mine       # patrols again
    # put while failed, moving again after the repair
    down = [(x, y) for t, x, y in xy if go + fail["t_fail"] + 1 < t < go + fail["t_repair"]]
    back = [(x, y) for t, x, y in xy if t > go + fail["t_repair"] + 1]
    assert len(down) >= 50 and back, (len(down), len(back))
    assert max(abs(x - down[0][0]) + abs(y - down[0][1]) for x, y in down) < 1e-3
    assert max(abs(x - down[-1][0]) + abs(y - down[-1][1]) for x, y in back) > 1.0
    assert len({v for t, r, v in visits if r != 1 and fail["t_fail"] < t < fail["t_repair"]}) \
        >= 5
    # the model at the receivers: about a fifth of the algorithm messages lost
    robots = scen["counters"]["robots"]
    assert sorted(robots) == [0, 1, 2]
    total = scen["counters"]["total"]
    assert total["sent"] == total["delivered"] + total["lost"] and total["sent"] >= 100
    assert 0.1 < total["lost"] / total["sent"] < 0.3, total
    assert robots[1]["ignored_failed"] > 0       # deaf while failed


def test_abstract_line_of_sight_drops_messages_through_walls(tmp_path):
    """Grid, 2 robots starting on opposite sides of an obstacle block, range 1000 m (far
    beyond the map: only walls can cut a link). With line of sight required, the
    receivers drop both /results and /positions messages; without, nothing is lost."""
    from patrolling_sim.model import map_bundle
    from patrolling_sim.scenarios.comm import line_of_sight
    from patrolling_sim.runner.config import ExperimentConfig
    cfg = ExperimentConfig(map="grid", robots=2, alg="SEBS", timeout=120,
                           results_dir=str(tmp_path))
    a, b = cfg.start_positions()
    assert not line_of_sight(map_bundle.load_map_bundle("grid")[0], a, b)   # placed accordingly
    totals = {}
    for los in ("true", "false"):
        out_dir = tmp_path / los
        out_dir.mkdir()
        proc = start(["--map", "grid", "--robots", "2", "--alg", "SEBS", "--nav", "abstract",
                      "--timeout", "120", "--speedup", "30", "--comm",
                      f"range:r=1000,los={los}"], out_dir)
        code, out = finish(proc)
        assert code == 0, out[-3000:]
        _, run, scen, _ = results(out_dir)
        assert run["status"] == "TIMEOUT" and scen["comm"] == f"range:r=1000,los={los}"
        totals[los] = scen["counters"]["total"]
    blocked, clear = totals["true"], totals["false"]
    assert blocked["results_sent"] >= 15 and blocked["positions_sent"] >= 200, blocked
    assert blocked["results_lost"] > 0 and blocked["positions_lost"] > 0, blocked
    assert blocked["delivered"] > 0, blocked            # in sight at times: not all lost
    assert clear["sent"] >= 200 and clear["lost"] == 0, clear
