"""Inputs of a graph-mode run (:mod:`patrolling_sim.graphsim.simulator`) and the world's constants
(``docs/protocol.md``, "Graph mode"; scenarios: ``docs/scenarios.md``)."""
import dataclasses
import math
from dataclasses import dataclass, field
from typing import Sequence

import yaml

from patrolling_sim.experiment import validation
from patrolling_sim.algorithms import REGISTRY
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import YamlDumper
from patrolling_sim.scenarios.scenario import check_scenario
from patrolling_sim.startpos.explicit import check_initpos

TIMERESULTS_PERIOD = 900.0
#: shortest trip (s): a goal on the robot's own vertex still takes one navigation cycle, so
#: simulated time always advances between two decisions of a robot
MIN_TRIP = 0.5
#: s between two navigation feedbacks (positions published, interference evaluated): the
#: move_base controller's 5 Hz
FEEDBACK_PERIOD = 0.2
TRAVEL_MODES = ("graph", "euclidean")
#: wall s between two flushes of the result rows (results.ResultWriter): the run's
#: ``finally`` closes the files on any ending but SIGKILL
WRITE_FLUSH_EVERY = 1.0


@dataclass
class GraphSimConfig:
    """Inputs of one graph-mode run (defaults as the ROS runner's)."""
    map: str = "grid"
    robots: int = 1
    alg: str = "CR"
    duration: float = 3600.0        # sim seconds after GO; 0 = until `cycles`
    cycles: int = 0                 # stop after this many complete patrol cycles; 0 = off
    seed: int = 0
    speed: float = 1.0              # m/s along graph edges (or straight lines)
    gwait: float = 0.0
    go_time: float = 0.0            # s the agents' clock ran before GO, as in ROS mode,
    #                                 where it starts with the simulator: the idleness of a
    #                                 vertex an agent has not visited counts from then
    #                                 (PatrolStrategy.clock_zero = -go_time)
    comm_delay: float = 0.0
    loss: float = 0.0
    initpos: str = "default"        # start positions, any form of
    #                                 patrolling_sim.startpos.resolve.start_positions
    #                                 ("default", a variant, "optimised", "vertices:...",
    #                                 "file:PATH", "random" drawn from seed); a robot starts
    #                                 on the vertex nearest its start position
    results_dir: str = "results"
    params: dict = field(default_factory=dict)
    goal_fail: float = 0.0          # probability that a navigation goal fails on the way
    interference: bool = True       # robots within 2 m interfere (the original's rule)
    positions: bool = True          # the agents hear their teammates' positions (/positions,
    #                                 from move_base feedback); False as in the abstract
    #                                 world, which sends no feedback: no interference, and
    #                                 CBLS's local team size stays its own id + 1
    travel: str = "graph"           # "graph": shortest graph path; "euclidean": straight line
    comm: str = "perfect"           # communication model (patrolling_sim.scenarios.comm, --comm)
    attrition: str = "none"         # robot failures (patrolling_sim.scenarios.attrition,
    #                                 --attrition)
    policy: str = ""                # policy file of --alg POLICY (params["policy"]); other
    #                                 algorithms ignore it

    def strategy_params(self) -> dict:
        """The strategy's params: ``params`` with ``policy`` (as an absolute path) if set."""
        return validation.strategy_params(self.params, self.policy)

    def validate(self):
        if self.alg not in REGISTRY:
            raise PatrolInputError(f"argument --alg: unknown algorithm '{self.alg}' (known: "
                                   f"{', '.join(sorted(REGISTRY))})")
        if self.robots < 1:
            raise PatrolInputError(f"argument --robots: team size must be >= 1, got {self.robots}")
        if self.duration < 0 or (self.duration == 0 and self.cycles <= 0):
            raise PatrolInputError("argument --duration: must be > 0 (or give --cycles)")
        if self.cycles < 0:
            raise PatrolInputError(f"argument --cycles: must be >= 0, got {self.cycles}")
        if self.speed <= 0:
            raise PatrolInputError(f"argument --speed: must be > 0, got {self.speed}")
        if self.gwait < 0:
            raise PatrolInputError(f"argument --gwait: must be >= 0, got {self.gwait}")
        if not 0 <= self.go_time < math.inf:
            raise PatrolInputError(f"argument --go-time: must be >= 0 and finite, got "
                                   f"{self.go_time}")
        if self.comm_delay < 0:
            raise PatrolInputError(f"argument --comm-delay: must be >= 0, got {self.comm_delay}")
        if not 0 <= self.loss < 1:
            raise PatrolInputError(f"argument --loss: must be in [0, 1), got {self.loss}")
        if not 0 <= self.goal_fail < 1:
            raise PatrolInputError(f"argument --goal-fail: must be in [0, 1), got {self.goal_fail}")
        if not self.positions and self.interference:
            raise PatrolInputError("argument --positions: off needs --interference off (the "
                                   "agents detect interference from their teammates' positions)")
        if self.travel not in TRAVEL_MODES:
            raise PatrolInputError(f"argument --travel: must be one of {', '.join(TRAVEL_MODES)}"
                                   f", got '{self.travel}'")
        # the same one-line errors as the experiment runner (patrolling_sim.experiment.validation)
        REGISTRY[self.alg].check_params(self.strategy_params())
        validation.check_map_files(self.map)
        check_initpos(self.initpos, self.robots)      # syntax and count, without the map
        check_scenario(self.comm, self.attrition, self.robots,
                       self.duration if self.duration > 0 else math.inf, self.seed)
        return self


def config_yaml(cfg: GraphSimConfig, start_vertices: Sequence[int]) -> str:
    """The text of a graph-mode run's ``<prefix>_config.yaml``: the fields of ``cfg`` and,
    after ``initpos``, the resolved ``start_vertices``. ``params`` that YAML cannot write
    (Python objects given from Python) are written as their ``repr``."""
    d = {}
    for key, value in dataclasses.asdict(cfg).items():
        d[key] = value
        if key == "initpos":
            d["start_vertices"] = [int(v) for v in start_vertices]
    try:
        return yaml.dump(d, Dumper=YamlDumper, sort_keys=False)
    except yaml.YAMLError:
        d["params"] = repr(cfg.params)
        return yaml.dump(d, Dumper=YamlDumper, sort_keys=False)
