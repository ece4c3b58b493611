"""The original's wall-clock draws, emulated (patrolling_sim.algorithms.wallclock): the
number drawn is glibc's first rand() after srand(second), every robot deciding in the same
emulated second draws it, the default stays the robot's seeded generator, bad params fail."""
import ctypes
import ctypes.util
import os
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))

from patrolling_sim.algorithms import wallclock  # noqa: E402
from patrolling_sim.common.errors import PatrolInputError  # noqa: E402
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402


class Clock:
    def __init__(self, t=0.0):
        self.t = t

    def now(self):
        return self.t


def test_a_draw_is_glibc_rand_after_srand_of_the_second():
    clock = Clock(41.0)
    d = wallclock.WallClockDraws(clock, pace=20.0, epoch=1)
    assert d.second(41.0) == 1 + 2 and d.second(39.99) == 1 + 1
    # glibc: srand(3); rand() == 1205554746
    assert d.choice(list(range(1000))) == 1205554746 % 1000
    seq = list(range(7))
    first = d.choice(seq)
    clock.t = 59.9                   # the same second: the same number
    assert d.choice(seq) == first
    other = wallclock.WallClockDraws(clock, pace=20.0, epoch=1)   # another robot
    assert other.choice(seq) == first
    picks = set()
    for k in range(40):              # other seconds, other numbers
        clock.t = 20.0 * k
        picks.add(d.choice(seq))
    assert len(picks) > 3


def test_draws_match_the_c_library():
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    clock = Clock()
    d = wallclock.WallClockDraws(clock, pace=30.0, epoch=1_700_000_000)
    for t in (0.0, 29.9, 30.0, 1234.5, 3599.9):
        clock.t = t
        libc.srand(d.second(t))
        assert d.choice(range(2 ** 31)) == libc.rand()


def test_default_is_the_seeded_generator_and_bad_params_fail():
    assert wallclock.from_params({}, Clock()) is None
    assert wallclock.from_params({wallclock.PACE_PARAM: 0}, Clock()) is None
    assert isinstance(wallclock.from_params({wallclock.PACE_PARAM: "30"}, Clock()),
                      wallclock.WallClockDraws)
    for bad in ({wallclock.PACE_PARAM: -1}, {wallclock.PACE_PARAM: "fast"},
                {wallclock.PACE_PARAM: float("inf")},
                {wallclock.PACE_PARAM: 20, wallclock.EPOCH_PARAM: 1.5}):
        with pytest.raises(PatrolInputError):
            wallclock.from_params(bad, Clock())


def _run(params, seed=0):
    return GraphSimulator(GraphSimConfig(map="grid", robots=4, alg="RAND", duration=300,
                                         seed=seed, params=params)).run(write=False)


def test_graph_mode_with_the_original_draws_is_reproducible_and_differs():
    p = {wallclock.PACE_PARAM: 60, wallclock.EPOCH_PARAM: 5}
    a, b, seeded = _run(p), _run(p), _run({})
    assert (a.total_visits, a.global_avg) == (b.total_visits, b.global_avg)
    assert [v.visits for v in a.per_vertex] != [v.visits for v in seeded.per_vertex]
