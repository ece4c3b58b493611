"""POLICY (a learned policy file, docs/learning.md) in ROS mode: on the full stack (grid, 4
robots, simulator and navigation, all agents in one patrol_agents process) every vertex is
visited; in the abstract world with one agent process per robot, the average idleness is
within 10 % of graph mode's with the same seed. Judged on sim-time figures only."""
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from abstract_runs import run_abstract  # noqa: E402
from rosenv import ros_env  # noqa: E402
from patrolling_sim.algorithms.policy import DEFAULT_POLICY  # noqa: E402
from patrolling_sim.common import paths  # noqa: E402
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402
from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402
from patrolling_sim.learned.policyfile import load_policy  # noqa: E402
from patrolling_sim.monitor.metrics import read_visits  # noqa: E402

ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
POLICY = paths.policy_file(DEFAULT_POLICY)
GRID_VERTICES = 25


def test_full_stack_visits_every_vertex(tmp_path):
    cmd = ["/usr/bin/python3", START, "--headless", "--map", "grid", "--robots", "4",
           "--alg", "POLICY", "--policy", POLICY, "--loc", "fake_localization",
           "--timeout", "150", "--speedup", "5", "--seed", "0", "--processes", "shared",
           "--results-dir", str(tmp_path)]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          env=ros_env(), cwd=str(tmp_path), timeout=600,
                          start_new_session=True)
    assert proc.returncode == 0, proc.stdout[-3000:]
    (info,) = list(tmp_path.rglob("*_info.csv"))
    prefix = str(info)[:-len("_info.csv")]
    fields = info.read_text().strip().split(";")
    assert fields[6] == "POLICY" and fields[7] == load_policy(POLICY).label
    assert fields[13] == "TIMEOUT", proc.stdout[-3000:]
    visited = {v for _, _, v in read_visits(prefix + "_visits.csv")}
    assert visited == set(range(GRID_VERTICES)), sorted(set(range(GRID_VERTICES)) - visited)
    with open(os.path.join(prefix + "_logs", "roslaunch.log"), errors="replace") as f:
        assert "Traceback" not in f.read()


def test_abstract_world_one_agent_per_process_matches_graph_mode(tmp_path):
    run = run_abstract("POLICY", 0, tmp_path, processes="separate", duration=300.0,
                       extra=("--policy", POLICY))
    assert run.exit_code == 0, run.output[-3000:]
    assert run.complete(300.0), run.output[-3000:]
    sim = GraphSimulator(GraphSimConfig(map="grid", robots=4, alg="POLICY", duration=300.0,
                                        seed=0, policy=POLICY))
    graph_avg = sim.run(write=False).global_avg
    assert abs(run.avg - graph_avg) <= 0.10 * graph_avg, (run.avg, graph_avg)
    assert {v for _, _, v in read_visits(run.prefix + "_visits.csv")} == \
        set(range(GRID_VERTICES))
