"""The abstract world holds its clock for the agents' messages (docs/abstract_world.md,
"Message hold", "GO hold", "Start hold"), and the run record says so: a DTAP run through the
runner (its own ROS master), whose auctions are answered before simulated time moves on."""
import glob
import os
import re

import yaml

from abstract_runs import run_abstract
from rosenv import ros_env

DURATION = 60.0


def test_message_hold_engages_for_dtap_and_reaches_the_run_record(tmp_path):
    r = run_abstract("DTAP", 1, tmp_path, duration=DURATION)
    assert r.exit_code == 0, r.output[-2000:]
    assert r.complete(DURATION), r.output[-2000:]
    with open(r.prefix + "_run.yaml", encoding="utf-8") as f:
        clock = yaml.safe_load(f)["clock"]
    assert clock["pace_requested"] == 30.0
    assert clock["pace_achieved"] > 0
    reasons = clock["reasons"]
    # every arrival is followed by a visit report, an idleness message and a task request
    # (at least one per robot in 60 s), each of which holds the clock
    assert reasons["message"]["holds"] >= 4, clock
    assert reasons["message"]["wall"] > 0, clock
    # the GO hold: from the team's ready announcements until GO, then 0.5 wall s from the
    # moment the world saw GO (it notices the hold within a step, so a little less may be
    # counted); a monitor that missed an announcement sends GO only after the robot's next
    # one, once the 2 wall s wait for GO timed out: then a second hold, at GO
    go_hold = reasons["go"]
    assert go_hold["holds"] in (1, 2) and go_hold["timeouts"] == go_hold["holds"] - 1, clock
    assert go_hold["wall"] >= 0.45, clock
    # the agents' reports (/sim_timers): every robot's start delay and auction ends are
    # timers the clock waits for, and every robot arrives at least once in 60 s
    assert set(reasons) == {"go", "message", "reaction", "timer", "arrival", "start"}, clock
    # the start hold: the clock stood still at its first step until the team was ready
    assert reasons["start"]["holds"] == 1 and reasons["start"]["timeouts"] == 0, clock
    assert reasons["timer"]["holds"] >= 4 and reasons["arrival"]["holds"] >= 4, clock
    assert clock["holds"] == sum(x["holds"] for x in reasons.values())
    assert clock["hold_timeouts"] == sum(x["timeouts"] for x in reasons.values())
    assert clock["held_wall"] > 0
    # every agent read GO at the monitor's GO time or one step (0.02 s) after it
    go = received = None
    for p in glob.glob(r.prefix + "_logs/*/*-stdout.log"):
        with open(p, encoding="utf-8", errors="replace") as f:
            for line in f:
                m = re.search(r", ([\d.]+)\]: All Robots GO", line)
                go = float(m.group(1)) if m else go
                m = re.search(r", ([\d.]+)\]: robot \d+: GO received", line)
                if m:
                    received = max(received or 0.0, float(m.group(1)))
    assert go is not None and received is not None
    assert received - go <= 0.02 + 1e-6, (go, received)
    # ... and GO came at the world's first step (the start hold), as in every run
    assert go == 0.02 or go_hold["timeouts"], (go, clock)


def test_bids_arrive_before_the_clock_moves(tmp_path, monkeypatch):
    """With the auction trace on, hardly any bid reaches the world after simulated time moved
    on from its request (the hold waits for it; without it, on a quiet machine at x30, the
    median bid came one 20 ms step late). A bid slower than the hold's quiet window (a
    heavily loaded machine) may still come late: at most one in ten here."""
    # the runs' environment is built once and cached: set the variable in it for this test
    monkeypatch.setitem(ros_env(), "PATROLLING_SIM_TRACE_AUCTIONS", "1")
    r = run_abstract("DTAP", 2, tmp_path, duration=DURATION)
    assert r.exit_code == 0, r.output[-2000:]
    logs = {os.path.realpath(p)
            for p in glob.glob(r.prefix + "_logs/*/abstract_world-*-stdout.log")}
    assert len(logs) == 1                   # (the folder "latest" links to the run's own)
    with open(logs.pop(), encoding="utf-8") as f:
        line = next(x for x in f if "auction bids traced" in x)
    m = re.search(r"auction bids traced: n (\d+),.* after the clock moved (\d+);", line)
    assert m, line
    bids, late = int(m.group(1)), int(m.group(2))
    assert bids >= 4 and late <= bids // 10, line


def test_the_default_pace_is_auto_with_the_figures_of_a_paced_run(tmp_path):
    """Unpaced (the runner's default in the abstract world) and x5 give the same figures:
    the start hold puts GO at the same sim time, the other holds keep the agents in step."""
    for d in ("auto", "x5"):
        (tmp_path / d).mkdir()
    auto = run_abstract("SEBS", 2, tmp_path / "auto", speedup=None, duration=DURATION)
    paced = run_abstract("SEBS", 2, tmp_path / "x5", speedup=5.0, duration=DURATION)
    for r in (auto, paced):
        assert r.exit_code == 0 and r.complete(DURATION), r.output[-2000:]
    with open(auto.prefix + "_run.yaml", encoding="utf-8") as f:
        clock = yaml.safe_load(f)["clock"]
    assert clock["pace_requested"] == "auto" and clock["pace_achieved"] > 0, clock
    assert auto.figures() == paced.figures()
