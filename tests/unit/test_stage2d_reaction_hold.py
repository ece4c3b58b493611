"""The simulator's reaction hold (``patrol_stage2d/reaction_hold.h``): the clock waits for a
robot whose goal ended until its next goal's first command, so that a decision costs the
same simulated time at any pace. The header is pure logic; this test compiles a small driver
(``src/patrol_stage2d/test/reaction_hold_check.cpp``) and feeds it event scripts with sim
and wall times given as numbers (no timing). Events: ``goal I ID SIM``, ``result I ID OK
SIM``, ``cmd I MOVING SIM``, ``hold SIM WALL`` (prints 1 if the clock stands still)."""
import pytest

import stage2d_driver


@pytest.fixture(scope="module")
def driver(tmp_path_factory):
    return stage2d_driver.build(tmp_path_factory, "reaction_hold_check")


def test_arrival_holds_until_the_next_goals_first_command(driver):
    out = driver("2 0 0 0.5 0.02", [
        "goal 0 g1 0", "cmd 0 1 0", "hold 0.1 0",       # driving: no hold
        "cmd 0 0 5.0", "result 0 g1 1 5.0", "hold 5.0 10.0",   # arrived: the clock waits
        "cmd 0 0 5.0", "hold 5.0 10.01",                # move_base's second stop: no reaction
        "goal 0 g2 5.0", "hold 5.0 10.02",              # goal seen, no command yet
        "cmd 0 0 5.0", "hold 5.0 10.025",               # the second stop came after the goal
        "cmd 0 1 5.0", "hold 5.0 10.03",                # its first command: the clock runs
        "counts"])
    assert out == ["0", "1", "1", "1", "1", "0", "1 0 0 0"]


def test_the_held_steps_do_not_depend_on_the_wall_time_taken(driver):
    """The same decision taking 10 or 200 wall ms: the clock stands at the same sim time."""
    for wall_taken in (0.01, 0.2):
        out = driver("1 0 0 0.5 0.02", [
            "goal 0 a 0", "cmd 0 1 0", "result 0 a 1 3.0", "hold 3.0 1.0",
            "goal 0 b 3.0", f"hold 3.0 {1.0 + wall_taken / 2}", "cmd 0 1 3.0",
            f"hold 3.0 {1.0 + wall_taken}"])
        assert out == ["1", "1", "0"]


def test_a_first_command_that_overtakes_its_goal_ends_the_hold(driver):
    """move_base's first command and the agent's goal travel on different connections."""
    out = driver("1 0 0 0.5 0.02", [
        "goal 0 a 0", "cmd 0 1 0", "result 0 a 1 3.0", "hold 3.0 1.0",
        "cmd 0 1 3.0", "hold 3.0 1.01", "goal 0 b 3.0", "hold 3.0 1.02",
        "cmd 0 0 8.0", "goal 0 c 8.0", "hold 8.0 2.0",    # a resend after a stop: held
        "cmd 0 1 8.0", "hold 8.0 2.01",
        "cmd 0 1 9.0", "goal 0 d 9.0", "hold 9.0 3.0"])   # a resend overtaken: not held
    assert out == ["1", "0", "0", "1", "0", "0"]


def test_goal_wait_and_reaction_time_are_simulated_time_the_agent_may_take(driver):
    out = driver("1 0.1 2.0 0.5 0.02", [
        "goal 0 a 0", "cmd 0 1 0", "result 0 a 1 10.0",
        "hold 10.0 0", "hold 12.0 1", "hold 12.1 2", "hold 12.1 2.1",
        "goal 0 b 12.1", "cmd 0 1 12.1", "hold 12.1 2.2"])
    assert out == ["0", "0", "1", "1", "0"]


def test_a_reaction_is_waited_for_at_most_wait_wall_seconds(driver):
    out = driver("1 0 0 0.5 0.02", [
        "goal 0 a 0", "cmd 0 1 0", "result 0 a 1 1.0",
        "hold 1.0 100.0", "hold 1.0 100.49", "hold 1.0 100.5", "hold 1.1 101.0",
        "counts",
        "goal 0 b 1.2", "hold 1.2 102.0", "cmd 0 1 1.2", "hold 1.2 102.1", "counts"])
    assert out == ["1", "1", "0", "0", "1 1 0 0", "1", "0", "2 1 0 0"]


def test_failures_and_pauses_are_not_held_but_the_resent_goal_is(driver):
    """Aborted or preempted goals: the agent backs up or pauses on purpose (sim time must
    pass); the goal it then resends is held for until move_base's first command."""
    out = driver("1 0 0 0.5 0.02", [
        "goal 0 a 0", "cmd 0 1 0", "cmd 0 0 4.0", "result 0 a 0 4.0", "hold 4.0 0",
        "hold 7.0 1", "goal 0 b 7.0", "hold 7.0 1.01", "cmd 0 1 7.0", "hold 7.1 1.02"])
    assert out == ["0", "0", "1", "0"]


def test_a_stale_result_starts_no_hold_and_wait_zero_never_holds(driver):
    stale = ["goal 0 a 0", "cmd 0 1 0", "goal 0 b 1.0", "cmd 0 1 1.0", "result 0 a 1 1.0",
             "hold 1.0 0"]
    assert driver("1 0 0 0.5 0.02", stale) == ["0"]
    never = ["goal 0 a 0", "cmd 0 1 0", "cmd 0 0 1.0", "result 0 a 1 1.0", "hold 1.0 0",
             "goal 0 b 1", "hold 1.0 1", "counts"]
    assert driver("1 0 0 0 0.02", never) == ["0", "0", "0 0 0 0"]


def test_robots_are_held_for_independently(driver):
    out = driver("2 0 0 0.5 0.02", [
        "goal 0 a 0", "goal 1 b 0", "cmd 0 1 0", "cmd 1 1 0",
        "result 0 a 1 2.0", "result 1 b 1 2.0", "hold 2.0 0",
        "goal 0 c 2.0", "cmd 0 1 2.0", "hold 2.0 0.1",
        "goal 1 d 2.0", "cmd 1 1 2.0", "hold 2.0 0.2", "counts"])
    assert out == ["1", "1", "0", "2 0 0 0"]


def test_a_driven_robots_stop_waits_briefly_for_its_result(driver):
    """move_base stops the robot, then publishes the result on another connection: the
    step after the stop waits for it (at most result_wait wall s), so that the stop is not
    applied before the hold can begin; a stop with no result (blocked) costs that wait once."""
    out = driver("1 0 0 0.5 0.02", [
        "goal 0 a 0", "cmd 0 1 0", "cmd 0 1 1.0",
        "cmd 0 0 2.0", "hold 2.0 5.0",                  # stopped: waits for a result
        "result 0 a 1 2.0", "hold 2.0 5.001",           # it came: the reaction hold
        "goal 0 b 2.0", "cmd 0 1 2.0", "hold 2.0 5.01",  # the new goal's command replaces the stop
        "cmd 0 0 3.0", "hold 3.0 6.0", "hold 3.0 6.019", "hold 3.0 6.03",  # blocked: no result
        "cmd 0 0 3.1", "hold 3.1 6.1",                  # still stopped: no new wait
        "counts"])
    assert out == ["1", "1", "0", "1", "1", "0", "0", "1 0 2 1"]


def test_a_robot_whose_goal_ended_is_not_a_driven_robot(driver):
    """The command wait waits for a robot stopped step after step by its controller (blocked)
    but not for one whose goal ended (any result) until it moves again."""
    out = driver("1 0 0 0.5 0.02", [
        "goal 0 a 0", "cmd 0 1 0", "ended 0", "cmd 0 0 1.0", "cmd 0 0 1.1", "ended 0",
        "result 0 a 0 1.2", "ended 0", "goal 0 b 4.2", "cmd 0 0 4.2", "ended 0",
        "cmd 0 1 4.2", "ended 0", "result 0 b 1 9.0", "ended 0"])
    assert out == ["0", "0", "1", "1", "0", "1"]
