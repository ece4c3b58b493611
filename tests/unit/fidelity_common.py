"""Shared by tests/unit/test_fidelity.py and bench/fidelity_table.py: the original's reference
runs under tests/unit/data/original_runs/ (see the README there), the further runs of the
original's own agents in this project's abstract world under
tests/unit/data/original_agents_abstract_world/ (README there), and the same experiment in
graph mode.

Every expected figure is read from the original's own result files: the average idleness is
the mean of the samples of ``*_idleness.csv``, the maximum and the visit count come from
``*_info.csv``, the duration too; the start vertices are those of the shipped ``grid_4``
start poses, as in the reference runs.
"""
import csv
import dataclasses
import glob
import os
import statistics

from patrolling_sim.algorithms import names
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.monitor.results import parse_info_line

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "original_runs", "grid_4")
#: more runs of the original's agents (built from its source), in this project's abstract world
#: with this project's monitor, for algorithms whose figures two reference runs cannot pin down
AGENT_DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data",
                          "original_agents_abstract_world", "grid_4")
#: the same, made two at a time beside the unit tests (a loaded machine, as in the test suite)
LOADED_AGENT_DATA = AGENT_DATA + "_loaded"
MAP, ROBOTS = "grid", 4


def run_dirs(alg, root=DATA):
    """The reference run directories of ``alg`` (sorted), [] if there are none; ``root``:
    another folder of runs laid out the same way (AGENT_DATA, LOADED_AGENT_DATA)."""
    return sorted(glob.glob(os.path.join(root, alg, "*", "")))


def reference_algorithms():
    """Registered algorithms that have runs of the original (the original's short names):
    reference runs, or runs of its agents in our abstract world (DTASSI, which the original
    builds but its launcher does not list, has only the latter)."""
    return [a for a in names() if run_dirs(a) or agent_run_dirs(a)]


def _one(run_dir, pattern):
    found = glob.glob(os.path.join(run_dir, pattern))
    if len(found) != 1:
        raise FileNotFoundError(f"{run_dir}: expected one {pattern}, found {len(found)}")
    return found[0]


def info(run_dir):
    path = _one(run_dir, "*_info.csv")
    with open(path, encoding="utf-8") as f:
        return parse_info_line(f.read(), path)


def idleness_rows(run_dir):
    with open(_one(run_dir, "*_idleness.csv"), encoding="utf-8") as f:
        return list(csv.DictReader(f, delimiter=";"))


def idleness_samples(run_dir):
    return [float(row["Idleness"]) for row in idleness_rows(run_dir)]


#: a robot with fewer idleness samples than this share of the team's mean per robot has
#: stopped patrolling in that run
STOPPED_ROBOT_SHARE = 0.5


def stopped_robots(run_dir):
    """Robots of a reference run that stopped patrolling (the original's CBLS agent exits
    when its learning step fails: in one CBLS run robot 0 made a single move)."""
    counts = {r: 0 for r in range(ROBOTS)}
    for row in idleness_rows(run_dir):
        counts[int(row["Robot"])] += 1
    mean = sum(counts.values()) / ROBOTS
    return [r for r, c in counts.items() if c < STOPPED_ROBOT_SHARE * mean]


def usable_run_dirs(alg):
    """Reference runs of ``alg`` in which every robot kept patrolling."""
    return [d for d in run_dirs(alg) if not stopped_robots(d)]


def agent_run_dirs(alg, loaded=False):
    """The runs of the original's ``alg`` agents in our abstract world (sorted), [] if none;
    ``loaded``: those made on a loaded machine (LOADED_AGENT_DATA)."""
    return run_dirs(alg, LOADED_AGENT_DATA if loaded else AGENT_DATA)


def figures(run_dir):
    """(avg idleness, max idleness, visits) of one run folder."""
    i = info(run_dir)
    return statistics.mean(idleness_samples(run_dir)), i["idl_max"], i["total_visits"]


def loaded_agent_figures(alg):
    """[(avg, max, visits)] of the original's ``alg`` agents in our abstract world on a loaded
    machine (LOADED_AGENT_DATA; README there), [] if none."""
    return [figures(d) for d in agent_run_dirs(alg, loaded=True) if not stopped_robots(d)]


def reference_figures(alg):
    """[(avg idleness, max idleness, visits)] of every usable run of the original's ``alg``:
    the reference runs and the runs of its agents in our abstract world (runs in which a robot
    of the original stopped are left out: see stopped_robots)."""
    return [figures(d) for d in usable_run_dirs(alg)
            + [d for d in agent_run_dirs(alg) if not stopped_robots(d)]]


def reference_duration():
    """Sim seconds after GO of the reference runs (all equal)."""
    durations = {info(d)["sim_duration"] for a in reference_algorithms() for d in run_dirs(a)}
    if len(durations) != 1:
        raise ValueError(f"{DATA}: reference runs differ in duration: {sorted(durations)}")
    return durations.pop()


def world_visits(run_dir, robot):
    """Vertices reported by ``robot`` in time order (world_visits.csv: sim_time;robot;vertex)."""
    with open(os.path.join(run_dir, "world_visits.csv"), encoding="utf-8") as f:
        rows = [r for r in csv.DictReader(f, delimiter=";") if int(r["robot"]) == robot]
    return [int(r["vertex"]) for r in sorted(rows, key=lambda r: float(r["sim_time"]))]


def config(alg, seed, duration=None):
    """Graph mode in the reference world: grid, 4 robots at the shipped default start poses,
    goal wait 0, no delay or loss, 1 m/s; straight-line travel where the simulator offers it
    (on grid every edge is straight, so travel along the graph is the same)."""
    kw = dict(map=MAP, robots=ROBOTS, alg=alg, seed=seed,
              duration=reference_duration() if duration is None else duration,
              speed=1.0, gwait=0.0, comm_delay=0.0, loss=0.0, initpos="default")
    fields = {f.name for f in dataclasses.fields(GraphSimConfig)}
    if "travel" in fields:
        kw["travel"] = "euclidean"
    if "interference" in fields:
        kw["interference"] = False
    return GraphSimConfig(**kw)


def simulator(alg, seed, duration=None):
    return GraphSimulator(config(alg, seed, duration))


def run_ours(alg, seed):
    """(avg idleness, max idleness, visits) of one graph-mode run."""
    s = simulator(alg, seed).run(write=False)
    return s.global_avg, s.global_max, s.total_visits
