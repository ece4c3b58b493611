"""The simulator's GO hold (``patrol_stage2d/go_hold.h``): the clock stands still from the
team's last ready announcement until GO, then ``go_wait`` wall s more, so that every agent
starts its patrol at the same sim time at any pace. The header is pure logic, the same rule
as the abstract world's ``clock_hold.GoHold`` (tests/unit/test_clock_hold.py); this test
compiles a small driver (``src/patrol_stage2d/test/go_hold_check.cpp``) and feeds it event
scripts with wall times given as numbers (no timing). Events: ``msg WALL A B C`` (prints 1 for
the first GO), ``hold WALL`` (prints ``1 END`` while the clock stands still, else ``0``),
``counts`` (the time-outs)."""
import pytest

import stage2d_driver


@pytest.fixture(scope="module")
def driver(tmp_path_factory):
    return stage2d_driver.build(tmp_path_factory, "go_hold_check")


def test_from_the_last_ready_until_go_then_go_wait(driver):
    out = driver("2 0.5 2", [
        "msg 1.0 0 10 1", "hold 1.0",        # one robot ready: no hold
        "msg 1.1 0 10 1", "hold 1.1",        # announced again
        "msg 1.2 1 10 1", "hold 1.2",        # the team is ready: wait for GO
        "msg 1.25 -1 10 100", "hold 1.3",    # GO: go_wait from now
        "hold 1.75", "counts",
        "msg 2.0 -1 10 100", "hold 2.0"])    # GO again: nothing new
    assert out == ["0", "0", "0", "0", "0", "1 3.2", "1", "1 1.75", "0", "0", "0", "0"]


def test_a_wait_without_go_times_out_once_and_is_not_repeated(driver):
    out = driver("1 0.5 2", [
        "msg 0 0 10 1", "hold 1.0", "hold 2.0", "counts",
        "msg 3.0 0 10 1", "hold 3.0",        # a late re-announcement starts no new wait
        "msg 4.0 -1 10 100", "hold 4.1",     # the GO that comes still holds
        "hold 4.5", "counts"])
    assert out == ["0", "1 2", "0", "1", "0", "0", "1", "1 4.5", "0", "1"]


def test_other_messages_and_bad_ids_change_nothing(driver):
    out = driver("2 0.5 2", [
        "msg 0 0 10 1", "msg 0 5 10 1", "msg 0 -1 10 1",   # ids outside the team
        "msg 0 1 11 1", "msg 0 1 10 2", "hold 0.1",          # other types and payloads
        "msg 0.2 1 10 1", "hold 0.2"])
    assert out == ["0"] * 6 + ["0", "1 2.2"]


def test_go_wait_zero_never_holds(driver):
    out = driver("1 0 2", ["msg 0 0 10 1", "hold 0.1", "msg 0.2 -1 10 100", "hold 0.2"])
    assert out == ["0", "0", "1", "0"]


def test_a_negative_wait_is_refused(driver):
    assert driver("1 -1 2", [], rc=3) == []
