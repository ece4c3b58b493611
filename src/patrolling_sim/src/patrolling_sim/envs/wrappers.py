"""The other forms of the learning environment (docs/learning.md): the AEC form through
PettingZoo's own conversion, and one centralised controller as a Gymnasium ``Env``."""
import gymnasium
import numpy as np
from gymnasium import spaces
from pettingzoo.utils.conversions import parallel_to_aec

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.envs.parallel import PatrolParallelEnv


def parallel_env(**kwargs) -> PatrolParallelEnv:
    """The ``ParallelEnv`` (arguments: :class:`~patrolling_sim.envs.options.EnvOptions`)."""
    return PatrolParallelEnv(**kwargs)


def aec_env(**kwargs):
    """The AEC form: ``pettingzoo.utils.conversions.parallel_to_aec`` of :func:`parallel_env`."""
    return parallel_to_aec(PatrolParallelEnv(**kwargs))


class CentralisedPatrolEnv(gymnasium.Env):
    """One controller for the whole team (libraries without multi-agent support).

    Observation: the robots' flat observations stacked, (N, F) float32 (zeros for failed
    robots). Action: ``MultiDiscrete([D] * N)`` (or ``[V] * N`` with ``action="goal"``), one
    entry per robot; only the ready robots' entries are used. Reward: the sum of the robots'
    rewards. ``terminated`` when every robot has failed, ``truncated`` at the time limit.
    ``info``: ``ready`` (N bools), ``action_mask`` (N, D) int8, ``time``, ``dt``, ``metrics``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(self, **kwargs):
        if kwargs.get("observation", "flat") != "flat":
            raise PatrolInputError("argument observation: the Gymnasium wrapper needs 'flat'")
        self.par = PatrolParallelEnv(**kwargs)
        self.render_mode = self.par.render_mode
        agents = self.par.possible_agents
        single = self.par.observation_space(agents[0])
        self.n = len(agents)
        self.observation_space = spaces.Box(single.low[0], single.high[0],
                                            (self.n, single.shape[0]), np.float32)
        self.action_space = spaces.MultiDiscrete(
            [self.par.action_space(a).n for a in agents])

    def _pack(self, obs, infos):
        out = np.zeros(self.observation_space.shape, dtype=np.float32)
        ready = np.zeros(self.n, dtype=bool)
        masks = np.zeros((self.n, self.action_space.nvec[0]), dtype=np.int8)
        any_info = {}
        for a, o in obs.items():
            i = self.par.agent_ids[a]
            out[i] = o
            ready[i] = infos[a]["ready"]
            masks[i] = infos[a]["action_mask"]
            any_info = infos[a]
        info = {"ready": ready, "action_mask": masks, "time": self.par.sim.t,
                "dt": any_info.get("dt", 0.0), "metrics": any_info.get("metrics", {})}
        return out, info

    def reset(self, seed=None, options=None):
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(2 ** 31))
        obs, infos = self.par.reset(seed=seed, options=options)
        return self._pack(obs, infos)

    def step(self, action):
        acts = {a: int(action[self.par.agent_ids[a]]) for a in self.par.agents}
        obs, rewards, terms, truncs, infos = self.par.step(acts)
        packed, info = self._pack(obs, infos)
        terminated = bool(terms) and all(terms.values())
        truncated = any(truncs.values()) and not terminated
        return packed, float(sum(rewards.values())), terminated, truncated, info

    def render(self):
        return self.par.render()

    def close(self):
        self.par.close()
