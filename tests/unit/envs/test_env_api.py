"""The learning environment keeps the PettingZoo and Gymnasium contracts: their own API
checks on the parallel env, its AEC conversion and the centralised wrapper; spaces cached;
seeded resets reproducible; state, render, infos; bad arguments are one-line errors."""
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import api_test, parallel_api_test

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.envs.parallel import PatrolParallelEnv
from patrolling_sim.envs.wrappers import CentralisedPatrolEnv, aec_env


@pytest.mark.parametrize("kwargs", [dict(), dict(action="goal"), dict(observation="graph")])
def test_parallel_api(kwargs):
    env = PatrolParallelEnv(map="grid", robots=3, duration=120.0, **kwargs)
    parallel_api_test(env, num_cycles=200)


def test_aec_api_on_the_converted_env():
    api_test(aec_env(map="grid", robots=3, duration=120.0), num_cycles=200)


def test_gymnasium_check_env_on_the_centralised_wrapper():
    env = CentralisedPatrolEnv(map="grid", robots=3, duration=120.0)
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape and info["ready"].any()
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs) and not terminated


def test_spaces_are_cached_and_ids_are_strings():
    env = PatrolParallelEnv(map="cumberland", robots=4, duration=60.0)
    assert env.possible_agents == ["robot_0", "robot_1", "robot_2", "robot_3"]
    for a in env.possible_agents:
        assert env.observation_space(a) is env.observation_space(a)
        assert env.action_space(a) is env.action_space(a)
    assert env.action_space("robot_0").n == env.max_degree


def rollout(env, seed, steps=150):
    """(actions, observations, rewards, times) of ``steps`` steps with actions drawn from a
    generator seeded with ``seed`` among the valid ones."""
    rng = np.random.default_rng(seed)
    obs, infos = env.reset(seed=seed)
    trace = [np.concatenate([obs[a] for a in sorted(obs)])]
    for _ in range(steps):
        if not env.agents:
            break
        acts = {a: int(rng.choice(np.flatnonzero(infos[a]["action_mask"]))) for a in env.agents}
        obs, rew, term, trunc, infos = env.step(acts)
        trace.append(np.concatenate([obs[a] for a in sorted(obs)] +
                                    [np.array([rew[a] for a in sorted(rew)])]))
    return trace, env.sim.t


def test_seeded_resets_are_reproducible():
    env = PatrolParallelEnv(map="grid", robots=4, duration=300.0, reward="avg_idleness_delta",
                            comm="bernoulli:p=0.2")
    a, ta = rollout(env, 5)
    b, tb = rollout(env, 5)
    other = PatrolParallelEnv(map="grid", robots=4, duration=300.0,
                              reward="avg_idleness_delta", comm="bernoulli:p=0.2")
    c, tc = rollout(other, 5)
    assert ta == tb == tc and len(a) == len(b) == len(c)
    for x, y, z in zip(a, b, c):
        assert np.array_equal(x, y) and np.array_equal(x, z)
    d, td = rollout(env, 6)
    assert td != ta or any(not np.array_equal(x, y) for x, y in zip(a, d))


def test_only_ready_robots_act_and_infos_carry_time_and_masks():
    env = PatrolParallelEnv(map="grid", robots=4, duration=200.0)
    obs, infos = env.reset(seed=0)
    t_prev = 0.0
    for _ in range(50):
        ready = [a for a in env.agents if infos[a]["ready"]]
        assert ready, "every step ends with a robot that must decide"
        before = {a: env.sim.robots[env.agent_ids[a]].core.target for a in env.agents}
        obs, rew, term, trunc, infos = env.step({a: 0 for a in env.agents})
        info = next(iter(infos.values()))
        assert info["dt"] == pytest.approx(info["time"] - t_prev) and info["dt"] >= 0
        t_prev = info["time"]
        for a, i in infos.items():
            assert i["action_mask"].dtype == np.int8 and i["action_mask"].any()
            assert set(i["metrics"]) >= {"avg_idleness", "max_idleness", "cycles"}
        for a in env.agents:        # robots that were not ready ignored their action
            if a not in ready and before[a] is not None:     # None: not started yet
                assert env.sim.robots[env.agent_ids[a]].core.target == before[a]


def test_state_and_render():
    env = PatrolParallelEnv(map="grid", robots=2, duration=60.0, render_mode="rgb_array")
    env.reset(seed=1)
    s = env.state()
    assert env.state_space.contains(s)
    img = env.render()
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8 and img.max() > 0


def test_time_limit_truncates_everyone():
    env = PatrolParallelEnv(map="grid", robots=2, duration=30.0)
    obs, infos = env.reset(seed=0)
    last = None
    while env.agents:
        last = env.step({a: 0 for a in env.agents})
    _, _, term, trunc, infos = last
    assert all(trunc.values()) and not any(term.values())
    assert env.sim.t == 30.0 and "stats" in next(iter(infos.values()))["metrics"]


@pytest.mark.parametrize("kwargs, words", [
    (dict(map="nowhere"), "unknown map"),
    (dict(action="jump"), "argument action"),
    (dict(reward="fun"), "argument reward"),
    (dict(robots=0), "argument robots"),
    (dict(duration=0), "argument duration"),
    (dict(comm="bogus:1"), "comm"),
    (dict(attrition="0@10+20"), "repairs"),
    (dict(map="random:n=1"), "n must be"),
    (dict(map="random:size=abc"), "must be a number"),
    (dict(map="grid", max_degree=1), "max_degree"),
    (dict(colour="red"), "unknown argument"),
])
def test_bad_arguments_are_one_line_errors(kwargs, words):
    with pytest.raises(PatrolInputError) as e:
        PatrolParallelEnv(**kwargs)
    assert words in str(e.value) and "\n" not in str(e.value)
