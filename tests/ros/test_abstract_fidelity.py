"""ROS mode against the original (issue 12): our agents and monitor, started by the runner
with ``--nav abstract --processes shared``, patrol grid with 4 robots for 600 sim s in the
abstract world, the world of the original's reference runs (docs/abstract_world.md). Each
algorithm's figures are compared with the mean of the original's runs, read from the
original's result files in tests/unit/data/original_runs/; and graph mode in the same world
(straight-line travel, no interference) gives the same average idleness.

Runs are shared by both comparisons and made two at a time (each has its own master; the
abstract world holds its clock for slow agents, so sharing the machine does not change the
sim-time figures). Every figure is a sim-time figure."""
import os
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "unit"))
import fidelity_common as fc  # noqa: E402
from abstract_runs import mean_figures, run_abstract  # noqa: E402

ALGS = ("CR", "CGG", "SEBS", "DTAG", "DTAP")
#: relative tolerances against the original's mean (issue 12 acceptance)
TOLERANCE = dict(avg=0.10, max=0.25, visits=0.10)
#: graph mode vs ROS mode, same algorithm, seed and world: average idleness
GRAPH_TOLERANCE = 0.05
#: runs per algorithm (seeds 0, 1, ...; their mean is compared). The maximum idleness of a
#: single 600 s run varies widely from seed to seed: CR 97-160 s in graph mode (seeds 0-11)
#: against the original's mean of 132.9 s; DTAP 80-151 s in graph mode (seeds 0-29, mean
#: 103.9 s) and 81-138 s in ROS mode (seeds 0-6, mean 102.6 s, 2026-11-25) against the
#: original's 98 s. One run would fail the 25 % bound by chance, so both are averaged (DTAP
#: over 4 runs: a standard error of about 10 s); the other algorithms' figures vary by a few
#: percent.
RUNS = {"CR": 2, "DTAP": 4}
PARALLEL = 2
#: (algorithm, figure) -> a known difference from the original in ROS mode
#: (docs/abstract_world.md), marked as an expected failure; none at present (DTAP's maximum,
#: once listed here, was the spread of single runs: docs/fidelity.md, DTAP)
KNOWN = {}


def _cases():
    out = []
    for alg in ALGS:
        for name in TOLERANCE:
            reason = KNOWN.get((alg, name))
            marks = [pytest.mark.xfail(reason=reason, strict=False)] if reason else []
            out.append(pytest.param(alg, name, id=f"{alg}-{name}", marks=marks))
    return out


@pytest.fixture(scope="module")
def ros_runs(tmp_path_factory):
    """alg -> [AbstractRun] for every algorithm of ALGS, all made on first use."""
    jobs = [(alg, seed) for alg in ALGS for seed in range(RUNS.get(alg, 1))]
    with ThreadPoolExecutor(PARALLEL) as pool:
        done = list(pool.map(lambda job: run_abstract(
            job[0], job[1], tmp_path_factory.mktemp(f"abstract_{job[0]}_{job[1]}")), jobs))
    out = {}
    for (alg, _), run in zip(jobs, done):
        out.setdefault(alg, []).append(run)
    return out


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
    tol = TOLERANCE[name]
    assert abs(ours - theirs) <= tol * theirs, (
        f"{alg} in ROS mode ({len(ros_runs[alg])} run(s)): {name} {ours:.2f} vs original "
        f"{theirs:.2f} ({(ours - theirs) / theirs:+.1%}, tolerance {tol:.0%}); runs "
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
