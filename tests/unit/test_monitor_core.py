"""MonitorCore metrics (facts section 5) and the result-file formats against the original's."""
import glob
import os
import re
import statistics

import pytest

from patrolling_sim.monitor.core import MonitorCore, population_sd
from patrolling_sim.monitor.results import (INFO_FIELDS, ResultWriter, RunInfo, default_prefix,
                                            parse_info_line)

#: files written by the original C++ monitor (copied from the reference material)
ORIG = os.path.join(os.path.dirname(__file__), "data", "original_output_example")


def test_handshake_true_once():
    c = MonitorCore(3, 2)
    assert c.robot_ready(0) is False
    assert c.robot_ready(0) is False
    assert c.robot_ready(5) is False          # not a team member
    assert c.robot_ready(1) is True
    assert c.robot_ready(1) is False


def test_visits_before_go_ignored():
    c = MonitorCore(2, 1)
    assert c.visit(0, 0, 5.0) is None
    c.interference(0, 5.0)
    assert c.interferences == 0 and c.visits == [-1, -1]


def test_first_visit_not_sampled_and_cycles():
    c = MonitorCore(2, 1)
    c.start(100.0)
    r = c.visit(0, 0, 100.0)          # start vertex report
    assert r.idleness is None and r.cycles == 0 and not r.new_cycle
    r = c.visit(0, 1, 110.0)
    assert r.idleness is None and r.cycles == 0
    r = c.visit(0, 0, 120.0)
    assert r.idleness == pytest.approx(20.0) and r.cycles == 0
    r = c.visit(0, 1, 125.0)
    assert r.idleness == pytest.approx(15.0) and r.cycles == 1 and r.new_cycle
    r = c.visit(0, 0, 130.0)
    assert r.idleness == pytest.approx(10.0) and r.cycles == 1 and not r.new_cycle
    s = c.stats(160.0)
    assert s.n_samples == 3
    assert s.global_min == pytest.approx(10.0) and s.global_max == pytest.approx(20.0)
    assert s.global_avg == pytest.approx(15.0)
    assert s.global_sd == pytest.approx(statistics.pstdev([20, 15, 10]))
    assert s.per_vertex[0].avg == pytest.approx(15.0) and s.per_vertex[0].visits == 2
    assert s.per_vertex[0].sd == pytest.approx(5.0)
    assert s.per_vertex[1].avg == pytest.approx(15.0) and s.per_vertex[1].sd == 0.0
    assert s.elapsed == pytest.approx(60.0)
    assert s.total_visits == 3 and s.avg_visits_per_node == pytest.approx(1.5)
    assert c.current_idleness(160.0) == pytest.approx([30.0, 35.0])


def test_node_level_metrics_and_interference_rate():
    c = MonitorCore(4, 2)
    c.start(0.0)
    for v in range(4):
        c.visit(0, v, 0.0)
    c.visit(0, 0, 10.0)
    c.visit(1, 1, 30.0)
    c.visit(1, 2, 40.0)
    for _ in range(3):
        c.interference(1, 45.0)
    s = c.stats(90.0)
    avgs = [10.0, 30.0, 40.0, 0.0]       # vertex 3 has no sample -> 0
    assert s.worst_avg == 40.0
    assert s.graph_avg == pytest.approx(statistics.mean(avgs))
    assert s.graph_median == pytest.approx(statistics.median(avgs))
    assert s.graph_sd == pytest.approx(statistics.pstdev(avgs))
    assert s.interference_rate == pytest.approx(3 / 90 * 60)
    assert s.cycles == 0                 # vertex 3 visited once only


def test_cycles_is_the_least_visit_count_after_every_report():
    """The cycle count is kept up to date report by report (not recounted over the
    vertices): after every report it equals the least number of counted visits of any
    vertex, and ``new_cycle`` is true exactly when it grew."""
    import random
    for seed in range(20):
        rng = random.Random(seed)
        n = rng.randint(1, 9)
        m = MonitorCore(n, 3)
        m.start(0.0)
        before = 0
        for k in range(rng.randint(1, 300)):
            # biased towards a few vertices, so the minimum lags and then jumps
            v = rng.randrange(n) if rng.random() < 0.3 else rng.randrange(max(1, n // 3))
            r = m.visit(rng.randrange(3), v, 1.0 + k)
            assert m.cycles == max(0, min(m.visits)) == r.cycles, (seed, k)
            assert r.new_cycle == (m.cycles > before)
            before = m.cycles


def test_min_rule_replaces_tiny_minimum():
    c = MonitorCore(1, 1)
    c.start(0.0)
    c.visit(0, 0, 0.0)
    c.visit(0, 0, 0.05)                  # sample 0.05 (< 0.1) -> replaced by the next
    c.visit(0, 0, 5.05)
    assert c.stats(6).global_min == pytest.approx(5.0)


def test_longest_silence_per_robot():
    """Hand-computed (times since GO at 100): robot 0 reports at 10 and 30 s, then at 140 s
    (gap 110); robot 1 at 50 s (50 since GO), fails at 60 s and is repaired at 130 s: its
    70 s down are not silence, its silence clock restarts at the repair."""
    c = MonitorCore(3, 2)
    assert c.silences(100.0) == []                 # before GO
    c.start(100.0)
    for robot, t in ((0, 110.0), (0, 130.0), (1, 150.0)):
        c.visit(robot, 0, t)
    c.robot_failed(1, 160.0)
    assert c.silences(225.0) == pytest.approx([95.0, 50.0])   # robot 1 down: no silence
    c.robot_repaired(1, 230.0)
    c.visit(0, 1, 240.0)
    assert c.silences(260.0) == pytest.approx([110.0, 50.0])
    assert c.silences(300.0) == pytest.approx([110.0, 70.0])  # robot 1's open silence
    c.visit(5, 2, 290.0)                           # an id outside the team: not listed
    assert len(c.silences(300.0)) == 2


def test_a_report_from_outside_the_team_counts_but_cannot_fail_the_run():
    """Robot 7 in a team of 2 reports once and goes quiet: its visit is an idleness sample
    (the original counts it), but the silence rule watches robots 0 and 1 only, so after
    the dead-robot time only a silent team member is listed."""
    c = MonitorCore(3, 2)
    c.start(0.0)
    c.visit(0, 0, 10.0)
    r = c.visit(7, 0, 20.0)
    assert r is not None and r.idleness == pytest.approx(10.0)
    assert c.n_samples == 1 and c.foreign_reports == 1
    c.visit(0, 1, 290.0)
    c.visit(1, 2, 295.0)
    assert c.silent_robots(400.0, 300.0) == []      # robot 7 silent for 380 s: not a FAIL
    assert c.silent_robots(600.0, 300.0) == [0, 1]
    assert len(c.silences(600.0)) == 2


def test_population_sd():
    assert population_sd(0, 0, 0) == 0.0
    xs = [1.0, 2.0, 4.0]
    assert population_sd(3, sum(xs), sum(x * x for x in xs)) == pytest.approx(statistics.pstdev(xs))


def _shape(line):
    """A line with its numbers masked, to compare layouts."""
    return re.sub(r"-?\d+(\.\d+)?", "#", line)


def _one_run(tmp_path):
    c = MonitorCore(25, 2)
    c.start(10.0)
    w = ResultWriter(str(tmp_path / "grid_2" / "CR" / "host" / "20260101_000000"),
                     RunInfo("grid", 2, alg="CR", hostname="host", date="20260101_000000"))
    t = 10.0
    for k in range(60):
        t += 3.3
        r = c.visit(k % 2, (k * 7) % 25, t)
        if r.idleness is not None:
            w.idleness_row(t, k % 2, (k * 7) % 25, r.idleness, c.interferences)
        if r.new_cycle:
            w.cycle_block(c.stats(t), 1.5)
    w.time_row(c.stats(t))
    w.write_info(c.stats(t), 2.0, "TIMEOUT")
    w.close()
    return w, c


def test_files_match_original_layout(tmp_path):
    w, c = _one_run(tmp_path)
    assert c.cycles >= 1
    orig = {os.path.basename(p).split("_", 2)[2]: p for p in glob.glob(os.path.join(ORIG, "2*_*"))}
    for suffix in ("idleness.csv", "timeresults.csv", "results.txt", "info.csv"):
        mine = open(w.path(suffix)).read().splitlines()
        theirs = open(orig[suffix]).read().splitlines()
        assert mine, suffix
        if suffix == "results.txt":
            # one block: compare shapes line by line, vertex rows included (25 vertices)
            n = theirs.index("-" * 160) + 3
            assert [_shape(x) for x in mine[:n]] == [_shape(x) for x in theirs[:n]]
        elif suffix == "info.csv":
            assert _shape(mine[0]).count(";") == 21 == _shape(theirs[0]).count(";")
            dm, dt = parse_info_line(mine[0]), parse_info_line(theirs[0])
            assert set(dm) == set(dt) == set(INFO_FIELDS)
        else:
            assert mine[0] == theirs[0]                 # header
            if len(theirs) > 1:
                assert {_shape(x) for x in mine[1:]} == {_shape(theirs[1])}


def test_info_roundtrip_and_errors(tmp_path):
    w, c = _one_run(tmp_path)
    d = parse_info_line(open(w.path("info.csv")).read())
    s = c.stats(c.time_zero + d["sim_duration"])
    assert d["complete_cycles"] == c.cycles and d["termination"] == "TIMEOUT"
    assert d["idl_avg"] == pytest.approx(s.global_avg, abs=0.051)
    with pytest.raises(ValueError, match="expected 22"):
        parse_info_line("a;b", "x_info.csv")
    bad = open(w.path("info.csv")).read().split(";")
    bad[10] = "zz"
    with pytest.raises(ValueError, match="sim_duration"):
        parse_info_line(";".join(bad), "x_info.csv")


def test_default_prefix():
    p = default_prefix("/r", "grid", 4, "CR", host="h", stamp="20260101_000000")
    assert p == "/r/grid_4/CR/h/20260101_000000"
