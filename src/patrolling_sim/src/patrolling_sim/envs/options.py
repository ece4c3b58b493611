"""The arguments of the learning environment (:class:`~patrolling_sim.envs.parallel.
PatrolParallelEnv`), checked once with one-line errors (PatrolInputError)."""
from dataclasses import dataclass
from typing import Optional

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.envs.graphs import RandomGraphSpec, parse_random_spec
from patrolling_sim.envs.rewards import REWARDS
from patrolling_sim.graphsim.config import TRAVEL_MODES

ACTIONS = ("neighbour", "goal")
OBSERVATIONS = ("flat", "graph", "slots")


@dataclass
class EnvOptions:
    """Every argument of the environment (docs/learning.md)."""
    map: str = "grid"
    robots: int = 4
    duration: float = 1800.0
    action: str = "neighbour"
    observation: str = "flat"
    reward: str = "visit"
    comm: str = "perfect"
    attrition: str = "none"
    initpos: Optional[str] = None
    speed: float = 1.0
    gwait: float = 0.0
    comm_delay: float = 0.0
    loss: float = 0.0
    goal_fail: float = 0.0
    interference: bool = True
    travel: str = "graph"
    max_degree: Optional[int] = None
    render_mode: Optional[str] = None
    seed: Optional[int] = None

    @property
    def random_spec(self) -> Optional[RandomGraphSpec]:
        """The random graph generator's parameters, None for a map."""
        m = self.map.strip()
        return parse_random_spec(m) if m == "random" or m.startswith("random:") else None

    def check(self):
        def one_of(name, value, allowed):
            if value not in allowed:
                raise PatrolInputError(f"argument {name}: must be one of "
                                       f"{', '.join(allowed)}, got '{value}'")
        one_of("action", self.action, ACTIONS)
        one_of("observation", self.observation, OBSERVATIONS)
        one_of("reward", self.reward, REWARDS)
        one_of("travel", self.travel, TRAVEL_MODES)
        if self.observation == "slots" and self.action != "neighbour":
            raise PatrolInputError("argument observation: 'slots' needs action='neighbour'")
        one_of("render_mode", self.render_mode, (None, "rgb_array"))
        if not isinstance(self.robots, int) or self.robots < 1:
            raise PatrolInputError(f"argument robots: must be an integer >= 1, got "
                                   f"{self.robots!r}")
        if not self.duration > 0:
            raise PatrolInputError(f"argument duration: must be > 0 s, got {self.duration!r}")
        if self.max_degree is not None and self.max_degree < 1:
            raise PatrolInputError(f"argument max_degree: must be >= 1, got {self.max_degree}")
        att = (self.attrition or "none").lower()
        if "+" in att or "repair" in att:
            raise PatrolInputError("argument attrition: repairs are not supported by the "
                                   "environment (a terminated agent cannot come back)")
        self.random_spec                       # raises on a bad random graph form
        return self
