"""The simulator's timer hold (``patrol_stage2d/timer_hold.h``): the clock stands still at a
step where an agent process has a timer due until the process reports that it fired (its
``/sim_timers`` report moves its earliest deadline on), at most ``wait`` wall s; a process
whose wait timed out is left out until it reports again. The header is pure logic, the same
rule as the abstract world's ``clock_hold.TimerReports`` (tests/unit/test_clock_hold.py);
this test compiles a small driver (``src/patrol_stage2d/test/timer_hold_check.cpp``) and
feeds it event scripts with sim and wall times given as numbers (no timing). Events:
``report NAME NEXT``, ``hold SIM WALL`` (prints 1 while the clock stands still, else 0),
``counts`` (``holds timeouts``)."""
import pytest

import stage2d_driver


@pytest.fixture(scope="module")
def driver(tmp_path_factory):
    return stage2d_driver.build(tmp_path_factory, "timer_hold_check")


def test_holds_at_the_step_of_a_due_timer_until_the_report_that_it_fired(driver):
    out = driver("0.5", [
        "report /agents 3.0",
        "hold 2.9 0.0",                  # not due yet
        "hold 3.0 0.1", "hold 3.0 0.3",  # due at this step: the clock stands still
        "report /agents 4.2",            # it fired; the next one is at 4.2
        "hold 3.0 0.35", "hold 4.1 0.4",
        "hold 4.2 0.5",                  # due again
        "report /agents -1", "hold 4.2 0.6", "counts"])
    assert out == ["0", "1", "1", "0", "0", "1", "0", "2 0"]


def test_every_reporter_is_waited_for_and_a_deadline_within_the_tolerance_is_due(driver):
    out = driver("0.5", [
        "report a 1.0", "report b 0.9999999",
        "hold 1.0 0", "report a 2.0", "hold 1.0 0.1", "report b -1", "hold 1.0 0.2"])
    assert out == ["1", "1", "0"]


def test_a_wait_that_reaches_its_bound_leaves_the_reporter_out_until_it_reports(driver):
    out = driver("0.5", [
        "report dead 1.0",
        "hold 1.0 10.0", "hold 1.0 10.49", "hold 1.0 10.5",   # time-out
        "hold 1.1 11.0", "hold 5.0 12.0",                     # left out
        "report dead 5.0", "hold 5.0 13.0",                   # it reports again: waited for
        "counts"])
    assert out == ["1", "1", "0", "0", "0", "1", "2 1"]


def test_a_new_step_starts_a_new_bound(driver):
    out = driver("0.5", [
        "report a 1.0", "hold 1.0 0.0", "report a 1.1", "hold 1.1 0.45",
        "hold 1.1 0.9", "hold 1.1 0.96", "counts"])
    assert out == ["1", "1", "1", "0", "2 1"]


def test_wait_zero_never_holds_and_a_negative_wait_is_refused(driver):
    assert driver("0", ["report a 1.0", "hold 1.0 0", "counts"]) == ["0", "0 0"]
    assert driver("-1", [], rc=3) == []
