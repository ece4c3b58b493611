"""The abstract world's motion model (src/patrolling_sim/tools/straight_line_world.py, used
by tools/abstract_world.py) and the runner's ``--nav abstract`` launch. No ROS master."""
import math
import os
import sys
import xml.etree.ElementTree as ET

import pytest

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.runner.config import ExperimentConfig
from patrolling_sim.runner.launchgen import generate_launch, status_topic

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "tools"))
import straight_line_world as aw  # noqa: E402

GRID = 5.7375          # m between neighbouring vertices of grid


def run_until_arrival(world, limit=100000):
    for _ in range(limit):
        arrived = world.advance()
        if arrived:
            return arrived
    raise AssertionError("no arrival")


def test_arrival_at_first_step_at_or_after_arrival():
    w = aw.StraightLineWorld([(1.425, 24.375)], speed=1.0, step=0.02)
    w.set_goal(0, 1.425 + GRID, 24.375)
    assert run_until_arrival(w) == [0]
    # 5.7375 m at 1 m/s = 286.875 steps of 20 ms: success at step 287
    assert w.steps == 287 and w.time == pytest.approx(5.74)
    assert w.pos[0] == [1.425 + GRID, 24.375] and not w.moving(0)
    assert w.advance() == []                   # stays there, no second success


def test_exact_multiple_of_the_step_arrives_on_that_step():
    w = aw.StraightLineWorld([(0.0, 0.0)], speed=2.0, step=0.05)
    w.set_goal(0, 3.0, 4.0)                    # 5 m at 2 m/s = 2.5 s = 50 steps
    run_until_arrival(w)
    assert w.steps == 50


def test_new_goal_starts_from_the_current_position():
    w = aw.StraightLineWorld([(0.0, 0.0)], speed=1.0, step=0.1)
    w.set_goal(0, 10.0, 0.0)
    for _ in range(30):
        w.advance()
    assert w.pos[0][0] == pytest.approx(3.0)
    w.set_goal(0, 3.0, 4.0)                    # straight up from (3, 0): 4 m
    start = w.steps
    run_until_arrival(w)
    assert w.steps - start == 40
    assert w.yaw[0] == pytest.approx(math.pi / 2)


def test_stop_freezes_the_robot():
    w = aw.StraightLineWorld([(0.0, 0.0)], speed=1.0, step=0.1)
    w.set_goal(0, 10.0, 0.0)
    for _ in range(25):
        w.advance()
    w.stop(0)
    for _ in range(100):
        assert w.advance() == []
    assert w.pos[0] == [pytest.approx(2.5), 0.0]


def test_robots_pass_through_each_other():
    w = aw.StraightLineWorld([(0.0, 0.0), (10.0, 0.0)], speed=1.0, step=0.02)
    w.set_goal(0, 10.0, 0.0)
    w.set_goal(1, 0.0, 0.0)
    assert sorted(run_until_arrival(w)) == [0, 1]
    assert w.steps == 500 and w.pos == [[10.0, 0.0], [0.0, 0.0]]


@pytest.mark.parametrize("flat,n,needle", [
    (None, None, "/initial_pos is not set"),
    ([1, 2, 3], 2, "~team_size 2 does not fit /initial_pos (1 positions)"),
    (["a", 2], None, "/initial_pos must be a flat list of numbers"),
    ([1, 2], 0, "~team_size 0 does not fit"),
])
def test_bad_positions_are_one_line_errors(flat, n, needle):
    with pytest.raises(ValueError) as e:
        aw.read_positions(flat, n)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_bad_motion_parameters():
    with pytest.raises(ValueError, match="~speed must be > 0"):
        aw.StraightLineWorld([(0, 0)], speed=0.0, step=0.02)
    with pytest.raises(ValueError, match="~step must be > 0"):
        aw.StraightLineWorld([(0, 0)], speed=1.0, step=-1)


def test_runner_launch_in_the_abstract_world(tmp_path):
    cfg = ExperimentConfig(map="grid", robots=4, alg="CR", nav="abstract", speedup=30,
                           timeout=600, results_dir=str(tmp_path)).validate()
    root = ET.fromstring(generate_launch(cfg, cfg.start_positions(),
                                         str(tmp_path / "20260101_000000")))
    worlds = [n for n in root.iter("node") if n.get("type") == "abstract_world.py"]
    assert len(worlds) == 1 and worlds[0].get("required") == "true"
    params = {p.get("name"): p.get("value") for p in worlds[0].iter("param")}
    assert params == {"team_size": "4", "speedup": "30.0", "start_wait": "120.0"}
    # no simulator, map server, localisation or move_base
    assert not list(root.iter("include"))
    assert {n.get("type") for n in root.iter("node")} == {"abstract_world.py", "monitor",
                                                          "patrol_agents"}
    assert status_topic(cfg) == "/abstract_world/status"
    # the grid_4 start poses: vertices 0, 13, 20, 11
    init = [float(v) for v in root.find("rosparam").text.strip("[]").split(",")]
    assert init == [1.425, 24.375, 12.825, 7.275, 24.375, 24.375, 12.825, 18.675]
    with pytest.raises(PatrolInputError, match="argument --nav: the abstract world has no "):
        ExperimentConfig(map="grid", robots=4, alg="CR", nav="abstract", record=True,
                         results_dir=str(tmp_path)).validate()


def test_auction_trace_summary():
    """The world's auction trace (PATROLLING_SIM_TRACE_AUCTIONS=1) summarises the delays
    from a task request to the bids on it, in sim and wall s."""
    from clock_hold import AuctionTrace
    t = AuctionTrace()
    assert t.summary() == "auction bids traced: none"
    for sim, wall, delay in [(1.0, 10.0, 0.02), (2.0, 11.0, 0.04), (3.0, 12.0, 0.6),
                             (4.0, 13.0, 1.2), (5.0, 14.0, 0.0)]:
        t.note([0, 41, 7, 100], sim, wall)
        t.note([1, 42, 7, 50], sim + delay, wall + 0.003)
    t.note([1, 42, 8, 50], 9.0, 20.0)          # no request on vertex 8: not a bid traced
    line = t.summary()
    assert line.startswith("auction bids traced: n 5,")
    assert "median 0.040" in line and "max 1.200" in line
    assert "over 0.5 s 2, over 1 s 1, after the clock moved 4" in line
    assert "wall ms median 3.0" in line


def test_a_goal_with_a_start_time_waits_for_it():
    """The reaction time: a goal given before ``start`` leaves at the first step that
    begins at or after it."""
    w = aw.StraightLineWorld([(0.0, 0.0)], speed=1.0, step=0.02)
    w.set_goal(0, 1.0, 0.0, start=0.08)
    for _ in range(4):
        w.advance()
    assert w.pos[0] == [0.0, 0.0] and w.moving(0)
    w.advance()                                # the step from 0.08 to 0.10 s moves
    assert w.pos[0][0] == pytest.approx(0.02)
    w.set_goal(0, 2.0, 0.0, start=0.0)         # a start in the past: at once
    w.advance()
    assert w.pos[0][0] == pytest.approx(0.04)
