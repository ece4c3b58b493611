"""ROS mode against the original: our agents and monitor, started by the runner
with ``--nav abstract --processes shared``, patrol grid with 4 robots for 600 sim s in the
abstract world, the world of the original's reference runs (docs/abstract_world.md). Each
algorithm's figures are compared with the mean of the original's runs, read from the
original's result files in tests/unit/data/original_runs/ and, for DTAP and DTASSI, from the
runs of the original's own agents in this world (tests/unit/data/original_agents_abstract_world/;
DTASSI has only those);
and graph mode in the same world
(straight-line travel, no interference) gives the same average idleness.

Runs are shared by both comparisons and made four at a time (each has its own master; the
abstract world holds its clock for slow agents and for the agents' messages, so sharing the
machine does not change the sim-time figures). Every figure is a sim-time figure.

A sample of the fidelity matrix (tests/unit/data/original_matrix/, docs/fidelity_matrix.md:
the original's own agents on the other maps, in this world) runs too: :data:`MATRIX_SAMPLE`,
one run each of our agents in the cell's conditions (default start positions, the runs'
duration, the monitor's dead-robot rule off), compared with the mean of the original's runs
of the cell within the matrix's tolerances."""
import math
import os
import statistics
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "unit"))
import fidelity_common as fc  # noqa: E402
import original_matrix as om  # noqa: E402
from abstract_runs import mean_figures, run_abstract  # noqa: E402

ALGS = ("CR", "CGG", "SEBS", "DTAG", "DTAP", "DTASSI")
#: relative tolerances against the original's mean
TOLERANCE = dict(avg=0.10, max=0.25, visits=0.10)
#: graph mode vs ROS mode, same algorithm, seed and world: average idleness
GRAPH_TOLERANCE = 0.05
#: runs per algorithm (seeds 0, 1, ...; their mean is compared). The maximum idleness of a
#: single 600 s run varies widely from run to run: CR 97-160 s in graph mode (seeds 0-11)
#: against the original's mean of 132.9 s; DTAG 103-137 s in graph mode (seeds 0-9, mean
#: 122 s) against the original's 134.2 s, so that one run at 103 s misses the 25 % bound
#: (100.6 s); SEBS 62-85 s in graph mode (seeds 0-29) but 57.7-98.8 s in ROS mode (24 runs
#: two at a time beside two CPU hogs; 3 of the 24 outside the 25 % bound of
#: 59.1-98.4 s) and 115.4 s once in CI, against the original's 78.8 s. So these are averaged
#: (DTAG over 3 runs, SEBS over 4: a 4-run mean drawn from those 25 runs misses the bound in
#: 0.2 % of draws). DTAP's maximum spreads most: the original's own agents gave 84.8-181.4 s
#: in 20 runs in this world (SD 24.6 s, tests/unit/data/original_agents_abstract_world/),
#: ours 79.1-152.9 s in 20 runs alternated with them (docs/fidelity.md). DTAP over 10 runs:
#: then the 25 % bound is at least three standard errors of the difference (tolerance()).
#: Load raised DTAP's maximum in the world before its message hold, the original's as ours:
#: two at a time beside the unit tests, the original's agents gave a mean of 136.0 s over
#: 12 runs, ours 133.1 s (12 runs alternated with them), and this test's 10 runs in one
#: suite 138.8 s; so DTAP is also
#: allowed the 25 % around the mean of those loaded runs of the original
#: (tests/unit/data/original_agents_abstract_world/grid_4_loaded/).
#: DTASSI's maximum spreads nearly as widely: the original's agents gave 77.6-176.3 s in 20
#: runs in this world (SD 24.7 s), ours 69.1-164.6 s in 19 runs alternated with them
#: (docs/fidelity.md); over 6 runs tolerance() widens its bound to three standard errors of
#: the difference.
#: CGG's maximum varies by a few percent (142-143 s, a fixed route).
RUNS = {"CR": 2, "SEBS": 4, "DTAG": 3, "DTAP": 10, "DTASSI": 6}
#: cells of the fidelity matrix run in ROS mode too (map, robots, algorithm): two maps other
#: than grid, algorithms whose original runs spread little (CGG's fixed route; HPCC's
#: idleness-weighted paths), so that one run of ours can be judged by the matrix's tolerances
MATRIX_SAMPLE = (("cumberland", 4, "CGG"), ("DIAG_floor1", 4, "HPCC"))
#: runs at a time: the world holds its clock for the agents' messages and decisions, so a run
#: spends much of its wall time waiting on short quiet windows, not computing
PARALLEL = 4
#: with at least this many runs of the original, the spread of its own runs is known well
#: enough to judge a mean of our runs by it (see tolerance())
SPREAD_RUNS = 10
#: standard errors of the difference of the two means allowed (see tolerance())
SPREAD_SE = 3.0


def tolerance(name, theirs, n_ours):
    """The relative tolerance for figure ``name`` of our mean over ``n_ours`` runs against the
    mean of the original's runs ``theirs`` (one value per run): TOLERANCE, or,
    where the original's own runs spread so widely that a mean of ``n_ours`` runs drawn from
    the same spread would often leave it by chance (DTAP's maximum: SD 24 s on a mean of
    111 s), SPREAD_SE standard errors of the difference of the two means, estimated from the
    original's runs (needs SPREAD_RUNS of them). A systematic difference of that size still
    fails."""
    tol = TOLERANCE[name]
    if len(theirs) >= SPREAD_RUNS:
        se = statistics.stdev(theirs) * math.sqrt(1 / n_ours + 1 / len(theirs))
        tol = max(tol, SPREAD_SE * se / statistics.mean(theirs))
    return tol


def _cases():
    out = []
    for alg in ALGS:
        for name in TOLERANCE:
            out.append(pytest.param(alg, name, id=f"{alg}-{name}"))
    return out


@pytest.fixture(scope="module")
def ros_runs(tmp_path_factory):
    """alg -> [AbstractRun] for every algorithm of ALGS, all made on first use."""
    # the matrix sample first: its runs are three times as long as the others (1800 sim s)
    jobs = [(cell, 0) for cell in MATRIX_SAMPLE]
    jobs += [(alg, seed) for alg in ALGS for seed in range(RUNS.get(alg, 1))]
    # the folders are made here, not in the pool's threads: pytest creates its base temporary
    # folder on the first mktemp without a lock, and two threads racing there made two base
    # folders and failed the module's setup ("abstract_CR_1 is not a normalized and relative
    # path", seen once in a full suite)
    dirs = [tmp_path_factory.mktemp("abstract_" + ("_".join(map(str, alg))
                                                   if isinstance(alg, tuple) else alg)
                                    + f"_{seed}") for alg, seed in jobs]
    with ThreadPoolExecutor(PARALLEL) as pool:
        done = list(pool.map(lambda job, d: _run(*job, d), jobs, dirs))
    out = {}
    for (alg, _), run in zip(jobs, done):
        out.setdefault(alg, []).append(run)
    return out


def _run(what, seed, results_dir):
    """A run of the reference world (``what`` an algorithm) or of a matrix cell (``what`` =
    (map, robots, algorithm): the cell's duration, the dead-robot rule off as in the
    original's runs of the matrix)."""
    if not isinstance(what, tuple):
        return run_abstract(what, seed, results_dir)
    map_name, robots, alg = what
    return run_abstract(alg, seed, results_dir, map_name=map_name, robots=robots,
                        duration=_matrix_cell(what)[0],
                        extra=("--dead-robot-timeout", "0"))


def _matrix_cell(cell):
    """(duration, the original's runs [(avg, max, visits)]) of a matrix cell."""
    found = [(key[3], runs) for key, runs in om.cells(om.read_rows()).items()
             if key[:3] == cell]
    assert len(found) == 1, f"the fidelity matrix has no single set of runs of {cell}"
    return found[0]


def check_complete(run, duration):
    tail = run.output[-3000:]
    assert run.exit_code == 0, f"runner exited {run.exit_code}:\n{tail}"
    assert run.info is not None, f"no info.csv:\n{tail}"
    # the run really covered the reference duration in sim time
    assert run.info["termination"] == "TIMEOUT", run.info
    assert run.info["sim_duration"] >= duration, run.info


@pytest.mark.parametrize("alg,name", _cases())
def test_ros_mode_matches_the_original(alg, name, ros_runs):
    ref_runs = fc.reference_figures(alg)
    assert ref_runs, f"no reference runs of {alg} in {fc.DATA}"
    for run in ros_runs[alg]:
        check_complete(run, fc.reference_duration())
    k = list(TOLERANCE).index(name)
    theirs = mean_figures(ref_runs)[k]
    ours = mean_figures([run.figures() for run in ros_runs[alg]])[k]
    tol = tolerance(name, [r[k] for r in ref_runs], len(ros_runs[alg]))
    low, high = (1 - tol) * theirs, (1 + tol) * theirs
    loaded = fc.loaded_agent_figures(alg)
    if loaded:
        # the original's agents were also measured on a loaded machine: within the tolerance
        # of either mean, since these runs may be made quiet or loaded
        theirs_loaded = mean_figures(loaded)[k]
        low = min(low, (1 - TOLERANCE[name]) * theirs_loaded)
        high = max(high, (1 + TOLERANCE[name]) * theirs_loaded)
    assert low <= ours <= high, (
        f"{alg} in ROS mode ({len(ros_runs[alg])} run(s)): {name} {ours:.2f} vs original "
        f"{theirs:.2f} over {len(ref_runs)} run(s) ({(ours - theirs) / theirs:+.1%}, "
        f"tolerance {tol:.1%}; allowed {low:.2f}-{high:.2f}"
        + (f", the original's agents loaded {theirs_loaded:.2f}" if loaded else "")
        + "); runs "
        f"{[run.figures() for run in ros_runs[alg]]}, agents' mean turnaround "
        f"{[run.turnaround for run in ros_runs[alg]]} sim s")


@pytest.mark.parametrize("alg", ("CR", "CGG"))
def test_graph_and_ros_mode_agree(alg, ros_runs):
    run = ros_runs[alg][0]                    # seed 0
    check_complete(run, fc.reference_duration())
    graph_avg = fc.run_ours(alg, 0)[0]
    assert abs(run.avg - graph_avg) <= GRAPH_TOLERANCE * graph_avg, (
        f"{alg}: ROS mode avg idleness {run.avg:.2f} s, graph mode {graph_avg:.2f} s "
        f"({(run.avg - graph_avg) / graph_avg:+.1%}, tolerance {GRAPH_TOLERANCE:.0%})")


@pytest.mark.parametrize("cell", MATRIX_SAMPLE, ids=lambda c: f"{c[0]}-{c[1]}-{c[2]}")
def test_ros_mode_matches_the_original_on_other_maps(cell, ros_runs):
    """Our agents in the abstract world against the original's own agents on a matrix cell:
    average idleness, maximum idleness and visits within the matrix's tolerances of the mean
    of the original's runs."""
    duration, theirs = _matrix_cell(cell)
    run = ros_runs[cell][0]
    check_complete(run, duration)
    cmp = om.compare(om.mean_figures(theirs), run.figures())
    bad = [f"{m} {rel:+.1%} (tolerance {om.TOL[m]:.0%})" for m, (rel, ok) in cmp.items()
           if not ok]
    assert not bad, (f"{cell}: ROS mode {run.figures()} against the original's mean "
                     f"{om.mean_figures(theirs)} over {len(theirs)} runs: " + "; ".join(bad))
