"""The graph-mode command line (``scripts/graph_sim.py``): one or more runs of
:class:`~patrolling_sim.graphsim.simulator.GraphSimulator`."""
import signal
import sys
import time

from patrolling_sim.common import paths
from patrolling_sim.monitor import run_status
from patrolling_sim.experiment import validation
from patrolling_sim.algorithms import REGISTRY
from patrolling_sim.graphsim.config import TRAVEL_MODES, GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.monitor.results import claim_prefix
from patrolling_sim.monitor.results import default_prefix
from patrolling_sim.common.cli import CliParser
from patrolling_sim.common.cli import run_main
from patrolling_sim.common.cli import setup_logging


def build_parser():
    """The argument parser of ``graph_sim.py`` (a :class:`CliParser`: one-line errors, exit
    status 2)."""
    ap = CliParser(prog="graph_sim.py", description=(
        "Run a patrolling experiment at graph level (no ROS): robots travel along the "
        "patrol graph at constant speed; same algorithms, metrics and result files as "
        "the ROS mode."))
    ap.add_argument("--map", default="grid", help="map name or path to its yaml/.graph")
    ap.add_argument("--robots", type=int, default=1, help="team size N")
    ap.add_argument("--alg", default="CR", help="algorithm: " + ", ".join(sorted(REGISTRY)))
    ap.add_argument("--duration", type=float, default=3600.0,
                    help="simulated seconds after GO (0: run until --cycles)")
    ap.add_argument("--cycles", type=int, default=0,
                    help="stop after this many complete patrol cycles (0: off)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--speed", type=float, default=1.0, help="robot speed (m/s)")
    ap.add_argument("--gwait", type=float, default=0.0, help="goal wait (s)")
    ap.add_argument("--go-time", type=float, default=0.0,
                    help="s the agents' clock ran before GO (default 0): as in ROS mode, "
                         "where it starts with the simulator, the idleness of a vertex an "
                         "agent has not visited counts from the clock's zero "
                         "(docs/fidelity.md, \"The clock at GO\")")
    ap.add_argument("--comm-delay", type=float, default=0.0, help="message delay (s)")
    ap.add_argument("--loss", type=float, default=0.0, help="message loss rate [0, 1)")
    ap.add_argument("--initpos", default="default",
                    help="start positions: 'default' (params/initial_poses.txt, else "
                         "computed), a variant letter of that table, 'optimised' (for --alg), "
                         "'vertices:V0,V1,...' (one vertex per robot), 'file:PATH' or a bare "
                         "path ('robot x y' / 'robot vertex' lines, or an [InitialPoses] "
                         "file; relative to the map's folder), or 'random' (distinct "
                         "vertices drawn from --seed); a pose starts a robot on its nearest "
                         "vertex")
    ap.add_argument("--goal-fail", type=float, default=0.0,
                    help="probability that a navigation goal fails on the way [0, 1)")
    ap.add_argument("--interference", choices=("on", "off"), default="on",
                    help="robots closer than 2 m interfere (default on)")
    ap.add_argument("--positions", choices=("on", "off"), default="on",
                    help="the agents hear their teammates' positions (default on); off as in "
                         "the abstract world, which sends no move_base feedback (needs "
                         "--interference off)")
    ap.add_argument("--travel", choices=TRAVEL_MODES, default="graph",
                    help="graph: along shortest graph paths; euclidean: straight line "
                         "to the goal vertex (default graph)")
    ap.add_argument("--comm", default="perfect",
                    help="communication model of inter-robot messages, e.g. "
                         "'bernoulli:p=0.1', 'ge:p_bad=0.8,to_bad=0.05,to_good=0.5', "
                         "'range:r=10,los=true', '...;delay=exp:0.3' (docs/scenarios.md)")
    ap.add_argument("--attrition", default="none",
                    help="robot failures: 'ROBOT@SECONDS[+REPAIR],...' or "
                         "'random:rate=R,min_team=K[,repair=S]' (docs/scenarios.md)")
    ap.add_argument("--policy", default="",
                    help="policy file (.npz) of --alg POLICY (default: the shipped "
                         "policies/slots_bc.npz; docs/learning.md)")
    ap.add_argument("--results-dir", default="results")
    ap.add_argument("--repeat", type=int, default=1,
                    help="run this many times with seeds seed, seed+1, ...")
    ap.add_argument("--quiet", action="store_true")
    return ap


def check_first_run(a):
    """Validate the first run of the parsed command line ``a`` before anything runs: its
    configuration, its start positions (a team-size warning is printed to stderr) and the
    results folder. Raises PatrolInputError on the first problem."""
    first = GraphSimConfig(map=a.map, robots=a.robots, alg=a.alg, duration=a.duration,
                           cycles=a.cycles, seed=a.seed, speed=a.speed, gwait=a.gwait,
                           go_time=a.go_time, comm_delay=a.comm_delay, loss=a.loss,
                           initpos=a.initpos, results_dir=a.results_dir, comm=a.comm,
                           attrition=a.attrition, policy=a.policy,
                           interference=a.interference == "on",
                           positions=a.positions == "on").validate()
    _, pgraph = validation.check_start_positions(first.map, first.robots, first.initpos,
                                                 alg=first.alg, seed=first.seed)
    warning = validation.team_size_warning(first.robots, pgraph.n, paths.map_name(a.map))
    if warning:
        print(warning, file=sys.stderr)
    validation.check_writable_dir(a.results_dir)


def run_config(a, seed):
    """The GraphSimConfig of the run with ``seed`` of the parsed command line ``a``."""
    return GraphSimConfig(map=a.map, robots=a.robots, alg=a.alg, duration=a.duration,
                          cycles=a.cycles, seed=seed, speed=a.speed, gwait=a.gwait,
                          go_time=a.go_time, comm_delay=a.comm_delay, loss=a.loss,
                          initpos=a.initpos, results_dir=a.results_dir, goal_fail=a.goal_fail,
                          interference=a.interference == "on",
                          positions=a.positions == "on", travel=a.travel,
                          comm=a.comm, attrition=a.attrition, policy=a.policy)


def record_interrupt(sim, sig):
    """After the run of ``sim`` was interrupted by ``sig`` ("SIGINT" or "SIGTERM"): if it
    has result files, mark its ``_run.yaml`` interrupted and say so on stderr. Returns the
    exit status of an interrupted run."""
    if sim.prefix:
        rec = run_status.read_run_yaml(sim.prefix) or {}
        rec.update(signal=sig, exit_code=run_status.exit_code_for(
            run_status.INTERRUPTED, sig), reason=f"interrupted by {sig}")
        run_status.write_run_yaml(sim.prefix, rec)
        print(f"interrupted by {sig}; results: {sim.prefix}_*", file=sys.stderr)
    return run_status.exit_code_for(run_status.INTERRUPTED, sig)


def run_one(cfg, quiet, got):
    """Run the experiment ``cfg`` and print its summary line and results prefix (its
    progress too unless ``quiet``). Returns None, or the exit status if a signal
    interrupted it (``got``: the SIGTERMs received; empty means SIGINT)."""
    t0 = time.monotonic()
    sim = GraphSimulator(cfg, log=None if quiet else print)
    # a map that is not a shipped one is filed under a name that cannot collide
    # with a shipped map (its name + a hash of its files), as in the ROS runner
    label = validation.result_map_name(cfg.map)
    if label != sim.map_name:
        sim.prefix = claim_prefix(default_prefix(cfg.results_dir, label, cfg.robots,
                                                 cfg.alg))
    try:
        stats = sim.run()
    except KeyboardInterrupt:
        return record_interrupt(sim, "SIGTERM" if got else "SIGINT")
    prefix = sim.prefix
    if label != sim.map_name:
        run_status.set_info_field(prefix, 0, label)
    avg = "-" if stats.global_avg is None else f"{stats.global_avg:.1f} s"
    mx = "-" if stats.global_max is None else f"{stats.global_max:.1f} s"
    print(f"{cfg.alg} on {paths.map_name(cfg.map)} with {cfg.robots} robot(s), seed "
          f"{cfg.seed}: {stats.elapsed:.0f} s simulated in {time.monotonic() - t0:.2f} s"
          f" | avg idleness {avg} | max {mx} | "
          f"cycles {stats.cycles} | visits {stats.total_visits}")
    print(f"results: {prefix}_*")
    return None


def run_command(args):
    """``graph_sim.py`` with the command line ``args``: the runs of seeds seed, seed+1, ...
    one after the other. SIGTERM ends a run as SIGINT does (its files kept). Returns the
    exit status (0, or that of an interrupted run); raises PatrolInputError on bad input."""
    ap = build_parser()
    a = ap.parse_args(args)
    setup_logging()
    got = []

    def on_term(signum, frame):     # SIGTERM ends the run as SIGINT does: files kept
        got.append(signum)
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, on_term)
    if a.repeat < 1:
        ap.error(f"argument --repeat: must be >= 1, got {a.repeat}")
    check_first_run(a)
    for k in range(a.repeat):
        rc = run_one(run_config(a, a.seed + k), a.quiet, got)
        if rc is not None:
            return rc
    return 0


def main(argv=None):
    """Entry point of ``scripts/graph_sim.py``: :func:`run_command` on ``argv`` (None: the
    process's arguments) with the project's error handling
    (:func:`patrolling_sim.common.cli.run_main`); returns the exit status."""
    return run_main(run_command, "graph_sim.py", argv)
