"""The slot observation of the learning environment, the POLICY strategy against the same
policy driven through the environment, and the training script (docs/learning.md)."""
import importlib.util
import os

import numpy as np
import pytest

from patrolling_sim.algorithms.policy import DEFAULT_POLICY
from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.envs.parallel import PatrolParallelEnv
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.learned.policyfile import load_policy
from patrolling_sim.learned.slots import K, SLOT_FEATURES

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
SHIPPED = paths.policy_file(DEFAULT_POLICY)


def test_slot_observation_space_and_rows():
    env = PatrolParallelEnv(map="cumberland", robots=3, duration=300.0, observation="slots")
    obs, infos = env.reset(seed=0)
    for _ in range(20):
        obs, _, _, _, infos = env.step({a: 0 for a in env.agents})
    D = env.max_degree
    for a in env.agents:
        o, mask = obs[a], infos[a]["action_mask"].astype(bool)
        assert o.shape == (D, K) and env.observation_space(a).contains(o)
        assert np.array_equal(o[:, SLOT_FEATURES.index("valid")] == 1, mask)
        assert not o[~mask].any()
        idle = o[mask, SLOT_FEATURES.index("idleness")]
        best = o[mask, SLOT_FEATURES.index("best")]
        assert np.array_equal(best == 1, idle >= idle.max() - 1e-6)
    with pytest.raises(PatrolInputError, match="slots"):
        PatrolParallelEnv(observation="slots", action="goal")


def env_run(policy, map_name, robots, seed, duration):
    env = PatrolParallelEnv(map=map_name, robots=robots, duration=duration,
                            observation="slots")
    obs, infos = env.reset(seed=seed)
    while env.agents:
        acts = {a: policy.choose(obs[a], infos[a]["action_mask"].astype(bool))
                for a in env.agents if infos[a]["ready"]}
        obs, _, _, _, infos = env.step(acts)
    return env.sim.monitor, env.final_stats


@pytest.mark.parametrize("map_name, robots, seed", [("grid", 4, 1), ("cumberland", 3, 2)])
def test_policy_strategy_equals_the_policy_through_the_environment(map_name, robots, seed):
    policy = load_policy(SHIPPED)
    mon_env, s_env = env_run(policy, map_name, robots, seed, 600.0)
    sim = GraphSimulator(GraphSimConfig(map=map_name, robots=robots, alg="POLICY",
                                        duration=600.0, seed=seed, policy=SHIPPED))
    s_sim = sim.run(write=False)
    assert s_sim.total_visits == s_env.total_visits > 0
    assert s_sim.global_avg == s_env.global_avg
    assert list(sim.monitor.last_visit) == list(mon_env.last_visit)


def test_training_smoke_gives_a_loadable_file(tmp_path):
    pytest.importorskip("torch")
    spec = importlib.util.spec_from_file_location(
        "train_policy", os.path.join(ROOT, "scripts", "train_policy.py"))
    trainer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(trainer)
    out = tmp_path / "tiny.npz"
    rc = trainer.main(["--out", str(out), "--maps",
                       "random:n=8,size=16,radius=8,max_degree=3,spacing=3", "--robots", "2",
                       "--duration", "60", "--iterations", "2", "--episodes", "1",
                       "--hidden", "4", "--eval-every", "2", "--eval-graphs", "1",
                       "--quiet"])
    assert rc == 0
    pol = load_policy(str(out))
    assert pol.meta["layers"] == [K, 4, 4, 1] and pol.meta["training"]["iterations"] == 2
    assert (tmp_path / "tiny.png").stat().st_size > 0 and (tmp_path / "tiny.yaml").exists()
    with pytest.raises(PatrolInputError, match="--gamma"):
        trainer.main(["--out", str(out), "--gamma", "1.5"])
