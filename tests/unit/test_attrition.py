"""Attrition schedules (patrolling_sim.scenarios.attrition): explicit and random, seeded,
validated."""
import pytest

from patrolling_sim.scenarios.attrition import Failure, describe, parse_attrition, random_schedule
from patrolling_sim.common.errors import PatrolInputError


def test_explicit_schedule_sorted_with_repairs():
    s = parse_attrition("5@1200, 2@600+300", team_size=6)
    assert s == [Failure(2, 600.0, 300.0), Failure(5, 1200.0, None)]
    assert s[0].back == 900.0 and s[1].back is None
    assert describe(s) == "2@600+300,5@1200"
    assert parse_attrition(describe(s), 6) == s
    assert parse_attrition("", 3) == [] and parse_attrition("none", 3) == []


@pytest.mark.parametrize("spec, words", [
    ("2@", "expected ROBOT@SECONDS"),
    ("7@100", "robot 7 is not in a team of 6"),
    ("1@100,1@200", "robot 1 fails at 200 s while already failed since 100 s"),
    ("1@100+50,1@200", None),
    ("0@1,1@1,2@1,3@1,4@1,5@1", "every robot of the team would be gone"),
    ("random:rate=0", "rate"),
    ("random:rate=1,min_team=9", "min_team must be an integer in [0, 6]"),
    ("random:rate=1,speed=2", "random takes rate"),
])
def test_bad_schedules_one_line(spec, words):
    if words is None:
        assert len(parse_attrition(spec, 6)) == 2
        return
    with pytest.raises(PatrolInputError) as e:
        parse_attrition(spec, 6, duration=3600)
    assert words in str(e.value) and str(e.value).startswith("--attrition: ")


def test_random_schedule_is_seeded_and_keeps_the_minimum_team():
    a = parse_attrition("random:rate=2,min_team=3", 6, duration=7200, seed=1)
    b = parse_attrition("random:rate=2,min_team=3", 6, duration=7200, seed=1)
    c = parse_attrition("random:rate=2,min_team=3", 6, duration=7200, seed=2)
    assert a == b and a != c
    assert len(a) == 3                         # no repair: 3 of 6 fail, 3 keep working
    assert len({f.robot for f in a}) == 3 and all(0 <= f.t <= 7200 for f in a)


def test_random_failure_rate_matches_its_definition():
    # with repair, each robot fails again and again: about rate x robot-hours working
    s = random_schedule(rate_per_hour=1.0, team_size=4, duration=3600 * 500, min_team=0,
                        repair=1.0, seed=3)
    assert len(s) == pytest.approx(4 * 500, rel=0.1)
    for f, g in zip(s, s[1:]):
        assert f.t <= g.t
