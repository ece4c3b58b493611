"""Experiment configuration: one dataclass, read from the original's positional command
line, from argparse flags, from a YAML file, or from the GUI, and validated before anything
starts.

Keys (YAML file = same names as the long flags, with ``-`` or ``_``)::

    map          shipped map name (or path to a map .yaml)          required
    robots       team size N >= 1                                    required
    alg          algorithm short name (RAND, CR, HCR, HPCC, CGG, MSP, GBS, SEBS, CBLS,
                 DTAG, DTAP, or any registered strategy)             required
    initpos      where the robots start (patrolling_sim.startpos):      (default)
                 "default" (the map's entry of params/initial_poses.txt, else computed), a
                 lettered variant of that table ("a", "b", ...), "optimised" (start
                 vertices chosen for the algorithm), "vertices:21,48,3" (one vertex per
                 robot), "file:PATH" or a bare PATH with a "/" or an extension (a start
                 file: [InitialPoses] INI, or lines "robot x y" / "robot vertex"; relative
                 to the map's folder), or "random" (distinct vertices drawn from seed)
    loc          AMCL | fake_localization                            (AMCL)
    nav          spqrel_nav_lite | ros | abstract                    (spqrel_nav_lite)
                 abstract: no simulator and no navigation; one node moves the robots in
                 straight lines at 1 m/s (the world of the original's reference runs,
                 docs/abstract_world.md); loc is ignored, no gui_sim / record
    gwait        goal_reached_wait, s >= 0                           (0)
    comm_delay   communication_delay, s >= 0                         (0)
    loss         lost_message_rate in [0, 1)                         (0)
    comm         communication model of inter-robot messages (patrolling_sim.scenarios.comm):
                 perfect | bernoulli:p=.. | ge:p_good=..,p_bad=..,to_bad=..,to_good=.. |
                 range:r=..,los=true|false, optionally ;delay=KIND:a[,b]      (perfect)
    attrition    robot failures (patrolling_sim.scenarios.attrition): none | "2@600,5@1200[+300]" |
                 random:rate=..,min_team=..[,repair=..] (seeded by seed)       (none)
                 see docs/scenarios.md
    timeout      sim seconds after GO; 0 = no timeout                (0)
    cycles       stop after k complete patrol cycles; 0 = no limit   (0)
    speedup      simulator pace (> 0): 1 = real time, 4 = four times faster; an upper
                 bound: the simulator waits for late navigation commands. "auto" (with
                 nav abstract only): no pace, each step as soon as the agents allow (stored
                 as 0; docs/pace.md)              (1; auto with nav abstract)
    seed         random seed of agents, simulator noise and "random" starts   (0)
    results_dir  results root                                        (<workspace>/results)
    rviz         open rviz (the package's launch/patrol.rviz)        (false)
    gui_sim      open the simulator's window                         (false)
    record       save simulator snapshots and assemble a video       (false)
    record_period  sim seconds between snapshots                     (1.0)
    dead_robot_timeout  sim s without a visit report before a robot is declared dead
                 (run status FAIL); 0 = never                        (300, the original's)
    force        run even when the memory estimate exceeds the machine's  (false)
    policy       policy file (.npz) of alg POLICY (docs/learning.md); ignored by the
                 other algorithms                                    ("")
    processes    shared | separate | pooled[:K] | pooled-separate[:K]  (shared)
                 shared: all agents in one process (patrol_agents) and each robot's
                 localisation + move_base in one process (robot_nav) -- same topics and
                 messages, about half the CPU with many robots; separate: one process per
                 node, as the original (patrol_agent per robot, amcl/fake_localization and
                 move_base apart); pooled: agents in one process and the navigation of all
                 robots in K nav_host processes (default K: 1 up to 8 robots, else 2);
                 pooled-separate: one agent process per robot (as a real robot runs it),
                 navigation pooled in K nav_host processes (docs/navigation.md)

``validate()`` raises :class:`PatrolInputError` with one line naming the key or argument.
A run's ``_config.yaml`` (:meth:`ExperimentConfig.to_yaml`) also records the resolved
``start_vertices``; reading such a file ignores them (``initpos`` and ``seed`` decide).
"""
import dataclasses
import logging
import math
import os
from dataclasses import dataclass, field
from typing import Optional

import yaml

from patrolling_sim.common import paths
from patrolling_sim.common.textfile import write_atomic
from patrolling_sim.model import map_bundle
from patrolling_sim.experiment import validation
from patrolling_sim.experiment.validation import process_layout
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.algorithms import REGISTRY
from patrolling_sim.runner.rosenv import workspace_env
from patrolling_sim.scenarios.scenario import check_scenario
from patrolling_sim.startpos.explicit import check_initpos

log = logging.getLogger(__name__)

LOC_MODES = ("AMCL", "fake_localization")
NAV_MODES = ("spqrel_nav_lite", "ros", "abstract")
NAV_ALIASES = {"spqrel_navigation": "spqrel_nav_lite", "spqrel": "spqrel_nav_lite"}
#: keys of a ``_config.yaml`` that record what the run resolved, not settings: ignored on
#: reading
RECORDED_KEYS = ("start_vertices",)


def default_results_dir():
    return os.path.join(paths.results_root(), "results")


@dataclass
class ExperimentConfig:
    map: str = None
    robots: int = None
    alg: str = None
    initpos: str = "default"
    loc: str = "AMCL"
    nav: str = "spqrel_nav_lite"
    gwait: float = 0.0
    comm_delay: float = 0.0
    loss: float = 0.0
    comm: str = "perfect"
    attrition: str = "none"
    timeout: float = 0.0
    cycles: int = 0
    speedup: Optional[float] = None     # None: 1, or auto with nav abstract (validate)
    seed: int = 0
    results_dir: str = field(default_factory=default_results_dir)
    rviz: bool = False
    gui_sim: bool = False
    record: bool = False
    record_period: float = 1.0
    processes: str = "shared"
    dead_robot_timeout: float = 300.0
    force: bool = False
    policy: str = ""

    # ------------------------------------------------------------------ conversion
    def to_dict(self):
        return dataclasses.asdict(self)

    def to_yaml(self, start_vertices=None):
        """The configuration as YAML; with ``start_vertices`` (the resolved start vertex of
        each robot) a ``start_vertices`` list follows ``initpos``."""
        d = {}
        for key, value in self.to_dict().items():
            d[key] = "auto" if key == "speedup" and value == validation.AUTO_PACE else value
            if key == "initpos" and start_vertices is not None:
                d["start_vertices"] = [int(v) for v in start_vertices]
        return yaml.safe_dump(d, sort_keys=False)

    def save(self, path):
        write_atomic(path, self.to_yaml())

    def updated(self, values, source="config"):
        """Copy with ``values`` (a dict of key -> raw value) applied and type-converted.
        Unknown keys and values of the wrong type raise PatrolInputError naming
        ``source`` and the key."""
        out = dataclasses.replace(self)
        types = {f.name: f.type for f in dataclasses.fields(self)}
        for raw_key, value in values.items():
            key = str(raw_key).replace("-", "_")
            if key == "comm_delay" or key == "commdelay":
                key = "comm_delay"
            if key in RECORDED_KEYS:
                continue
            if key not in types:
                raise PatrolInputError(f"{source}: unknown key '{raw_key}' (known: "
                                       f"{', '.join(types)})")
            if value is None:
                continue
            if key == "speedup":
                where = ("argument --speedup" if source == "command line"
                         else f"{source}: key '{raw_key}'")
                setattr(out, key, validation.pace_value(value, where))
                continue
            setattr(out, key, _convert(value, types[key], f"{source}: key '{raw_key}'"))
        return out

    # ------------------------------------------------------------------ validation
    def check_environment(self):
        """What running (not only validating) needs around the run, checked before anything
        starts: a display for ``--rviz`` and ``--gui-sim`` (``$DISPLAY``), and a map name
        without whitespace (the agents and the monitor get it as one command-line word, as
        in the original). Returns self.

        Raises:
            PatrolInputError: one line naming the argument.
        """
        for flag, wanted in (("--rviz", self.rviz), ("--gui-sim", self.gui_sim)):
            if wanted and not os.environ.get("DISPLAY"):
                raise PatrolInputError(f"argument {flag}: needs a display and DISPLAY is not "
                                       f"set (run under X or xvfb-run, or drop {flag})")
        name = paths.map_name(self.map)
        if any(c.isspace() for c in name):
            raise PatrolInputError(f"argument --map: the map's name '{name}' holds a space; "
                                   "the nodes take it as one command-line word: rename its "
                                   "files (a folder with spaces is fine)")
        return self

    def validate(self, check_start_positions=True, check_writable=True):
        """Check every field; return self. Raises PatrolInputError (one line)."""
        if not self.map:
            raise PatrolInputError("argument --map: a map is required")
        validation.check_map_files(self.map)
        if self.robots is None:
            raise PatrolInputError("argument --robots: a team size is required")
        if self.robots < 1:
            raise PatrolInputError(f"argument --robots: team size must be >= 1, got {self.robots}")
        if not self.alg:
            raise PatrolInputError("argument --alg: an algorithm is required")
        if self.alg not in REGISTRY:
            raise PatrolInputError(f"argument --alg: unknown algorithm '{self.alg}' (known: "
                                   f"{', '.join(sorted(REGISTRY))})")
        REGISTRY[self.alg].check_params(self.strategy_params())
        self.nav = NAV_ALIASES.get(self.nav, self.nav)
        if self.loc not in LOC_MODES:
            raise PatrolInputError(f"argument --loc: must be one of {', '.join(LOC_MODES)}, "
                                   f"got '{self.loc}'")
        if self.nav not in NAV_MODES:
            raise PatrolInputError(f"argument --nav: must be one of {', '.join(NAV_MODES)}, "
                                   f"got '{self.nav}'")
        if self.nav == "abstract" and (self.gui_sim or self.record):
            raise PatrolInputError("argument --nav: the abstract world has no simulator window "
                                   "(drop --gui-sim and --record)")
        if process_layout(self.processes, self.robots)[1] == "pooled" and self.nav == "ros":
            raise PatrolInputError(f"argument --processes: '{self.processes}' pools our "
                                   f"navigation (spqrel_nav_lite) in nav_host processes; the "
                                   f"ROS packages of --nav ros run one per robot (use shared "
                                   f"or separate)")
        for name in ("gwait", "comm_delay", "timeout", "record_period", "dead_robot_timeout"):
            if getattr(self, name) < 0:
                raise PatrolInputError(f"argument --{name.replace('_', '-')}: must be >= 0, "
                                       f"got {getattr(self, name)}")
        self.speedup = validation.resolve_pace(self.speedup, self.nav)
        if not 0 <= self.loss < 1:
            raise PatrolInputError(f"argument --loss: must be in [0, 1), got {self.loss}")
        failures = self.scenario()[1]       # one-line errors for --comm / --attrition
        warning = validation.failure_timeout_warning(failures, self.nav,
                                                     self.dead_robot_timeout)
        if warning:
            log.warning("%s", warning[len("warning: "):])
        if self.cycles < 0:
            raise PatrolInputError(f"argument --cycles: must be >= 0, got {self.cycles}")
        if self.record and self.record_period <= 0:
            raise PatrolInputError("argument --record-period: must be > 0 when recording")
        if not self.initpos:
            self.initpos = "default"
        check_initpos(self.initpos, self.robots)    # syntax and count, without the map
        bundle = None
        if check_start_positions:
            # the map and its graph, read once: start poses, team size and memory estimate
            bundle = map_bundle.load_map_bundle(self.map)
            self.start_positions(bundle)    # one-line error when they cannot be placed
            warning = validation.team_size_warning(self.robots, bundle[1].number_of_nodes(),
                                                   self.map_name)
            if warning:
                log.warning("%s", warning[len("warning: "):])
        if self.nav == "abstract":
            figures = (0, 0)                # no navigation processes
        elif bundle is not None:
            figures = validation.memory_figures(*bundle)
        else:
            figures = validation.map_memory_figures(self.map)
        validation.check_memory(self.robots, self.processes, *figures, self.nav,
                                force=self.force)
        if check_writable:
            check_writable_dir(self.results_dir, "argument --results-dir")
        if self.nav == "ros":
            try:
                env = workspace_env()
            except PatrolInputError:
                env = None
            validation.check_ros_navigation(self.loc, env)
        return self

    def strategy_params(self):
        """The agents' ``~params``: ``{"policy": absolute path}`` if ``policy`` is set."""
        return validation.strategy_params({}, self.policy)

    def scenario(self):
        """(communication model, failure schedule) of this run, from ``comm`` and
        ``attrition`` (the random attrition model is drawn from ``seed`` over ``timeout``).

        Raises PatrolInputError (one line naming --comm or --attrition)."""
        self.comm = str(self.comm or "perfect").strip() or "perfect"
        self.attrition = str(self.attrition or "none").strip() or "none"
        return check_scenario(self.comm, self.attrition, self.robots or 0,
                              duration=self.timeout if self.timeout > 0 else math.inf,
                              seed=self.seed, what_comm="argument --comm",
                              what_attr="argument --attrition")

    def start_poses(self, bundle=None):
        """(positions, PatrolGraph): [(x, y)] for the team (any ``initpos`` form,
        :func:`patrolling_sim.experiment.validation.check_start_positions`) and the map's
        graph; validates the team size. ``bundle``: the map's (OccupancyMap, graph) if
        already loaded (:func:`patrolling_sim.model.map_bundle.load_map_bundle`). Raises
        PatrolInputError (one line) when they cannot be placed."""
        return validation.check_start_positions(self.map, self.robots, self.initpos,
                                                alg=self.alg, seed=self.seed, bundle=bundle)

    def start_positions(self, bundle=None):
        """[(x, y)] for the team: the positions of :meth:`start_poses`."""
        return self.start_poses(bundle)[0]

    @property
    def map_name(self):
        return paths.map_name(self.map)

    @property
    def result_name(self):
        """Name the results are filed under (a user map gets a content hash, see
        :func:`patrolling_sim.experiment.validation.result_map_name`)."""
        return validation.result_map_name(self.map)


def _convert(value, typ, where):
    try:
        if typ in (bool, "bool"):
            if isinstance(value, bool):
                return value
            s = str(value).strip().lower()
            if s in ("1", "true", "yes", "on"):
                return True
            if s in ("0", "false", "no", "off"):
                return False
            raise ValueError
        if typ in (int, "int"):
            if isinstance(value, bool):
                raise ValueError
            f = float(value)
            if f != int(f):
                raise ValueError
            return int(f)
        if typ in (float, "float"):
            if isinstance(value, bool):
                raise ValueError
            f = float(value)
            if f != f or f in (float("inf"), float("-inf")):
                raise ValueError
            return f
        return str(value)
    except (TypeError, ValueError):
        tname = getattr(typ, "__name__", typ)
        raise PatrolInputError(f"{where}: expected {tname}, got {value!r}") from None


def check_writable_dir(path, what):
    """Create ``path`` if needed and check a file can be written in it."""
    validation.check_writable_dir(path, what)


def load_config_file(path, base=None):
    """Read a YAML experiment configuration (a mapping of keys as above)."""
    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except FileNotFoundError:
        raise PatrolInputError(f"{path}: configuration file not found") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f":{mark.line + 1}" if mark else ""
        raise PatrolInputError(f"{path}{where}: invalid YAML") from None
    except OSError as e:
        raise PatrolInputError(f"{path}: cannot read configuration ({e.strerror})") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise PatrolInputError(f"{path}: configuration must be a mapping of keys to values")
    return (base or ExperimentConfig()).updated(data, path)


POSITIONAL = ("map", "robots", "initpos", "alg", "loc", "nav", "gwait", "comm_delay",
              "term", "timeout", "custom_stage", "speedup")


def from_positional(args):
    """The original's form: MAP NROBOTS INITPOS ALG LOC NAV GWAIT COMMDELAY TERM TIMEOUT
    [CUSTOM_STAGE] [SPEEDUP]. TERM and CUSTOM_STAGE are accepted and ignored (no terminal
    windows, our simulator has no custom build)."""
    if not 10 <= len(args) <= 12:
        raise PatrolInputError(
            f"positional form needs 10 to 12 arguments (MAP NROBOTS INITPOS ALG LOC NAV GWAIT "
            f"COMMDELAY TERM TIMEOUT [CUSTOM_STAGE] [SPEEDUP]), got {len(args)}")
    values = {}
    for name, value in zip(POSITIONAL, args):
        if name in ("term", "custom_stage"):
            if name == "custom_stage":
                _convert(value, bool, "argument CUSTOM_STAGE")
            continue
        values[name] = value
    cfg = ExperimentConfig()
    for name, value in values.items():
        where = f"argument {name.upper()}"
        if name == "speedup":
            cfg.speedup = validation.pace_value(value, where)
            continue
        typ = {f.name: f.type for f in dataclasses.fields(cfg)}[name]
        setattr(cfg, name, _convert(value, typ, where))
    return cfg
