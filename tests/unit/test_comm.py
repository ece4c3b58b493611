"""Communication models (patrolling_sim.scenarios.comm) against their definitions: loss rates and
burst lengths within statistical tolerance for a seed, delays, range and line of sight on a
small map with a wall, parsing and one-line errors."""
import math
import statistics

import numpy as np
import pytest

from patrolling_sim.scenarios.comm import (Bernoulli, GilbertElliott, line_of_sight, parse_comm)
from patrolling_sim.common.errors import PatrolInputError
from spqrel_nav_lite.mapio import OccupancyMap

N = 40000


def _binomial_tol(p, n, k=5):
    return k * math.sqrt(p * (1 - p) / n)


def test_perfect_delivers_everything_without_delay():
    m = parse_comm("perfect")
    assert all(m.link(0, 1, t * 0.1) == 0.0 for t in range(100))
    assert m.counters() == {"sent": 100, "delivered": 100, "lost": 0}


@pytest.mark.parametrize("p", [0.0, 0.1, 0.5])
def test_bernoulli_loss_rate(p):
    m = parse_comm(f"bernoulli:p={p}", seed=3)
    lost = sum(m.link(0, 1, k * 0.01) is None for k in range(N))
    assert lost / N == pytest.approx(p, abs=_binomial_tol(p, N) + 1e-12)
    assert m.lost == lost and m.delivered == N - lost


def test_bernoulli_links_are_independent():
    m = Bernoulli(p=0.5, seed=1)
    a = [m.link(0, 1, k) is None for k in range(N)]
    b = [m.link(0, 2, k) is None for k in range(N)]
    both = sum(x and y for x, y in zip(a, b)) / N
    assert both == pytest.approx(0.25, abs=_binomial_tol(0.25, N))


def test_gilbert_elliott_loss_rate_and_bursts():
    # bad 1/6 of the time; a bad period lasts 1/0.5 = 2 s on average; lose everything when
    # bad, nothing when good: messages every 0.1 s
    m = parse_comm("ge:p_good=0,p_bad=1,to_bad=0.1,to_good=0.5", seed=11)
    assert m.bad_share == pytest.approx(1 / 6) and m.loss_rate == pytest.approx(1 / 6)
    dt = 0.1
    lost = [m.link(0, 1, k * dt) is None for k in range(N * 5)]
    rate = sum(lost) / len(lost)
    # samples are correlated: allow for bursts (about 20 messages each)
    assert rate == pytest.approx(1 / 6, rel=0.1)
    bursts, run = [], 0
    for x in lost:
        if x:
            run += 1
        elif run:
            bursts.append(run)
            run = 0
    # a bad period seen every dt lasts a geometric number of samples with leaving
    # probability 1 - exp(-to_good dt)
    expected = 1 / (1 - math.exp(-0.5 * dt))
    assert statistics.mean(bursts) == pytest.approx(expected, rel=0.1)


def test_gilbert_elliott_state_losses():
    m = GilbertElliott(p_good=0.02, p_bad=0.6, to_bad=0.2, to_good=0.2, seed=5)
    lost = sum(m.link(0, 1, k * 3.0) is None for k in range(N))     # nearly independent states
    assert lost / N == pytest.approx(m.loss_rate, abs=0.02)


@pytest.mark.parametrize("spec, mean, sd", [
    ("perfect;delay=const:0.5", 0.5, 0.0),
    ("perfect;delay=uniform:0.2,0.6", 0.4, 0.4 / math.sqrt(12)),
    ("perfect;delay=exp:0.3", 0.3, 0.3),
    ("perfect;delay=normal:2,0.1", 2.0, 0.1),
])
def test_delay_distributions(spec, mean, sd):
    m = parse_comm(spec, seed=2)
    d = np.array([m.link(0, 1, k) for k in range(N)])
    assert (d >= 0).all()
    assert d.mean() == pytest.approx(mean, abs=5 * sd / math.sqrt(N) + 1e-9)
    assert d.std() == pytest.approx(sd, rel=0.05, abs=1e-9)


def _walled_map():
    # 20 x 20 cells of 0.5 m: free, with a wall at x in [5, 5.5) m from y = 0 to 8 m
    data = np.zeros((20, 20), dtype=np.int8)
    data[:16, 10] = 100
    return OccupancyMap(data, 0.5)


def test_line_of_sight_on_a_map_with_a_wall():
    occ = _walled_map()
    assert not line_of_sight(occ, (2.0, 2.0), (8.0, 2.0))        # through the wall
    assert line_of_sight(occ, (2.0, 9.0), (8.0, 9.0))            # above its end
    assert line_of_sight(occ, (2.0, 2.0), (4.0, 7.0))            # same side
    assert not line_of_sight(occ, (2.0, 9.5), (8.0, 1.0))        # diagonal through it
    assert not line_of_sight(occ, (2.0, 2.0), (12.0, 2.0))       # leaves the map


def test_range_model_range_and_line_of_sight():
    occ = _walled_map()
    pos = {0: (2.0, 2.0), 1: (8.0, 2.0), 2: (2.0, 7.0), 3: (8.0, 7.0), 4: (7.0, 9.0)}
    m = parse_comm("range:r=6.5,los=true", occupancy=occ)
    assert m.link(0, 1, 0.0, pos.get) is None            # 6 m but behind the wall
    assert m.link(0, 2, 0.0, pos.get) == 0.0             # 5 m, same side
    assert m.link(2, 3, 0.0, pos.get) is None            # 6 m, through the wall's top
    assert m.link(2, 4, 0.0, pos.get) == 0.0             # 5.4 m, passing above the wall
    no_los = parse_comm("range:r=6.5,los=false", occupancy=occ)
    assert no_los.link(0, 1, 0.0, pos.get) == 0.0        # the wall is ignored
    assert no_los.link(1, 2, 0.0, pos.get) is None       # 7.8 m: out of range
    assert m.link(0, 9, 0.0, pos.get) is None            # unknown position: lost


def test_describe_round_trips():
    for spec in ("perfect", "bernoulli:p=0.25", "ge:p_good=0.01,p_bad=0.8,to_bad=0.05,"
                 "to_good=0.5;delay=exp:0.2", "range:r=12,los=false;delay=uniform:0.1,0.4",
                 "perfect;delay=normal:0.5,0.1"):
        assert parse_comm(spec).describe() == spec


@pytest.mark.parametrize("spec, words", [
    ("carrier-pigeon", "unknown communication model 'carrier-pigeon'"),
    ("bernoulli:q=0.1", "model 'bernoulli' takes p=..."),
    ("bernoulli:p=1.5", "p must be in [0, 1]"),
    ("bernoulli:p=lots", "p must be a number"),
    ("ge:to_bad=0", "to_bad must be > 0"),
    ("range:r=-1", "r must be > 0"),
    ("range:los=maybe", "los must be true or false"),
    ("perfect;delay=gamma:1", "unknown delay distribution 'gamma'"),
    ("perfect;delay=uniform:1", "takes 2 parameter(s)"),
    ("perfect;delay=uniform:2,1", "high < low"),
    ("perfect;jitter=1", "expected ';delay="),
])
def test_bad_specifications(spec, words):
    with pytest.raises(PatrolInputError) as e:
        parse_comm(spec)
    assert words in str(e.value) and str(e.value).startswith("--comm: ")


def test_seeded_models_repeat():
    a = [parse_comm("ge:p_good=0.1,p_bad=0.9,to_bad=1,to_good=1;delay=exp:1", seed=4)
         for _ in range(2)]
    assert [a[0].link(0, 1, k * 0.3) for k in range(500)] == \
        [a[1].link(0, 1, k * 0.3) for k in range(500)]
