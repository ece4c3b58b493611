"""A robot's agent as both drivers build it: :func:`build_agent` puts a
:class:`~patrolling_sim.agent.core.PatrolAgentCore` around the registered strategy of an
algorithm and the ``--comm`` model at this robot, and :func:`agent_seed` gives each robot of a
run its seed, the same in graph mode and in ROS mode (docs/protocol.md).
"""
import random

from patrolling_sim.agent.core import Effects, PatrolAgentCore
from patrolling_sim.agent.faults import make_comm
from patrolling_sim.algorithms.base import StrategyContext, create


def agent_seed(run_seed: int, robot_id: int) -> int:
    """The seed of robot ``robot_id``'s agent in a run seeded ``run_seed``, the same in graph
    mode and in ROS mode (the runner hands it to each agent): with the same run seed a
    robot's strategy draws the same numbers and waits the same start delay in both modes."""
    return int(run_seed) * 1000 + int(robot_id) + 1


def build_agent(effects: Effects, graph, robot_id: int, team_size: int, map_name: str,
                algorithm: str, start_vertex: int, start_position=None, seed: int = 0,
                params=None, goal_wait: float = 0.0, comm_delay: float = 0.0,
                loss: float = 0.0, comm="perfect", occupancy=None, positions=None,
                silence_check: bool = False, strategy_class=None) -> PatrolAgentCore:
    """A :class:`PatrolAgentCore` running the registered strategy ``algorithm``; the
    strategy's own generator is ``random.Random(seed)``. ``comm`` is a ``--comm`` spec (or a
    model), applied at this robot as the receiver, seeded ``seed * 7919 + 3``; ``occupancy``
    is the map for the range model's line of sight (:mod:`patrolling_sim.agent.faults`).
    ``strategy_class`` (a :class:`PatrolStrategy` subclass, registered or not) replaces the
    registered ``algorithm``'s class when given (a learning environment's decision maker).

    Raises:
        KeyError: unknown algorithm (one-line message listing the known ones).
    """
    def factory(driver):
        ctx = StrategyContext(graph=graph, robot_id=robot_id, team_size=team_size,
                              map_name=map_name, rng=random.Random(seed), driver=driver,
                              params=dict(params or {}),
                              start_position=None if start_position is None
                              else tuple(start_position))
        if strategy_class is not None:
            return strategy_class(ctx)
        return create(algorithm, ctx)
    return PatrolAgentCore(effects, robot_id, start_vertex, factory, seed=seed,
                           goal_wait=goal_wait, comm_delay=comm_delay, loss=loss,
                           comm=make_comm(comm, seed, occupancy), positions=positions,
                           silence_check=silence_check)
