"""``scripts/start_experiments.py``: start patrolling experiments (GUI, headless, batches).

Forms::

    start_experiments.py                         # Tk GUI (needs a display)
    start_experiments.py MAP NROBOTS INITPOS ALG LOC NAV GWAIT COMMDELAY TERM TIMEOUT \\
                         [CUSTOM_STAGE] [SPEEDUP]  # the original's positional form
    start_experiments.py --map grid --robots 4 --alg CGG --loc fake_localization \\
                         --timeout 300 --speedup 4 [...]
    start_experiments.py --config exp.yaml [flags that override it]
    start_experiments.py --batch batch.yaml --parallel 2

Everything is validated before anything starts; errors are one line and exit status 2.
A run exits 0 when it ended normally (TIMEOUT, CYCLES, STOPPED), 1 on FAIL or ABORTED, 3
when a node crashed, 130 on SIGINT, 143 on SIGTERM (patrolling_sim.monitor.run_status); the status
is recorded in info.csv and ``<prefix>_run.yaml``. With ``--batch``, flags given on the
command line override every entry of the batch; a batch exits 0 only if every run did.
"""
import os
import signal
import sys

from patrolling_sim.common.cli import CliParser, run_main, setup_logging
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.runner.batch import (BatchInterrupted, SignalHold, load_batch,
                                         print_batch_table, run_batch)
from patrolling_sim.runner.config import ExperimentConfig, from_positional, load_config_file
from patrolling_sim.runner.gui import run_gui
from patrolling_sim.runner.supervisor import Experiment
from patrolling_sim.runner.outcome import read_info
from patrolling_sim.scenarios.scenario import read_scenario
from patrolling_sim.runner.video import assemble_video

FLAG_KEYS = ("map", "robots", "initpos", "alg", "loc", "nav", "gwait", "comm_delay", "loss",
             "timeout", "cycles", "speedup", "seed", "results_dir", "record_period", "processes",
             "dead_robot_timeout", "comm", "attrition", "policy")
BOOL_KEYS = ("rviz", "gui_sim", "record", "force")


def build_parser():
    ap = CliParser(prog="start_experiments.py",
                   description="Start multi-robot patrolling experiments.")
    ap.add_argument("positional", nargs="*", metavar="ARG",
                    help="original form: MAP NROBOTS INITPOS ALG LOC NAV GWAIT COMMDELAY TERM "
                         "TIMEOUT [CUSTOM_STAGE] [SPEEDUP]")
    ap.add_argument("--config", help="YAML experiment configuration (flags override it)")
    ap.add_argument("--map")
    ap.add_argument("--robots", type=int)
    ap.add_argument("--initpos", help="start positions: 'default' (params/initial_poses.txt, "
                    "else computed), a variant letter of that table, 'optimised' (for --alg), "
                    "'vertices:V0,V1,...' (one vertex per robot), 'file:PATH' or a bare path "
                    "('robot x y' / 'robot vertex' lines, or an [InitialPoses] file; relative "
                    "to the map's folder), or 'random' (distinct vertices drawn from --seed)")
    ap.add_argument("--alg", help="algorithm short name")
    ap.add_argument("--loc", help="AMCL | fake_localization")
    ap.add_argument("--nav", help="spqrel_nav_lite | ros | abstract (straight-line world)")
    ap.add_argument("--gwait", type=float, help="goal_reached_wait (s)")
    ap.add_argument("--comm-delay", dest="comm_delay", type=float, help="communication delay (s)")
    ap.add_argument("--loss", type=float, help="lost message rate [0, 1)")
    ap.add_argument("--comm", help="communication model of /results and /positions: perfect "
                    "(default) | bernoulli:p=P | ge:p_good=..,p_bad=..,to_bad=..,to_good=.. | "
                    "range:r=M,los=true [;delay=const:S|uniform:A,B|exp:M|normal:M,SD] "
                    "(docs/scenarios.md)")
    ap.add_argument("--attrition", help="robot failures: none (default) | 'ROBOT@S[+REPAIR],...' "
                    "(sim s after GO) | random:rate=PER_ROBOT_HOUR,min_team=K[,repair=S]")
    ap.add_argument("--policy", help="policy file (.npz) of --alg POLICY (default: the "
                    "shipped policies/slots_bc.npz; docs/learning.md)")
    ap.add_argument("--timeout", type=float, help="sim seconds after GO (0 = none)")
    ap.add_argument("--cycles", type=int, help="stop after k complete patrol cycles")
    ap.add_argument("--speedup",
                    help="simulator pace > 0 (1 = real time; an upper bound, see the README), "
                    "or auto with --nav abstract (as fast as the agents allow)")
    ap.add_argument("--seed", type=int)
    ap.add_argument("--processes", help="shared (default: agents in one process, each robot's "
                    "localisation + navigation in one) | separate (one process per node) | "
                    "pooled[:K] (agents in one process, navigation of all robots in K "
                    "nav_host processes) | pooled-separate[:K] (one agent process per robot, "
                    "navigation pooled)")
    ap.add_argument("--results-dir", dest="results_dir")
    ap.add_argument("--dead-robot-timeout", dest="dead_robot_timeout", type=float,
                    help="sim seconds without a visit before a robot is declared dead "
                         "(status FAIL; default 300 as the original, 0 = never)")
    ap.add_argument("--force", action="store_true", default=None,
                    help="run even when the memory estimate exceeds the available memory")
    ap.add_argument("--rviz", action="store_true", default=None, help="open rviz")
    ap.add_argument("--gui-sim", dest="gui_sim", action="store_true", default=None,
                    help="open the simulator window")
    ap.add_argument("--record", action="store_true", default=None,
                    help="save snapshots and assemble a video of the run")
    ap.add_argument("--record-period", dest="record_period", type=float,
                    help="sim seconds between snapshots (default 1)")
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--headless", action="store_true", help="no GUI (default with arguments)")
    mode.add_argument("--gui", action="store_true", help="open the Tk launcher")
    ap.add_argument("--batch", help="YAML batch file (list or grid of configurations)")
    ap.add_argument("--parallel", type=int, default=1, help="batch runs at a time (default 1)")
    ap.add_argument("--dry-run", action="store_true",
                    help="validate and write the launch file, do not run")
    return ap


def flag_overrides(args):
    """The configuration keys given as flags on the command line."""
    return {k: getattr(args, k) for k in FLAG_KEYS + BOOL_KEYS
            if getattr(args, k, None) is not None}


def config_from_args(args):
    if args.positional:
        cfg = from_positional(args.positional)
    elif args.config:
        cfg = load_config_file(args.config)
    else:
        cfg = ExperimentConfig()
    if args.positional and args.config:
        cfg = load_config_file(args.config, cfg)
    return cfg.updated(flag_overrides(args), "command line")


def safe_print(*args, **kw):
    """print that survives a closed stdout (the reader of a pipe went away): the run must
    still be recorded."""
    try:
        print(*args, flush=True, **kw)
    except (OSError, ValueError):
        pass


def run_one(cfg, out=safe_print):
    """Run one validated experiment in this process; returns its Outcome."""
    exp = Experiment(cfg, out=out)

    # SIGINT / SIGTERM only set a flag that the supervisor checks several times a second,
    # so a signal at any moment (launch, wait for GO, run, shutdown) ends the run in order.
    # SIGINT is handled even when this process inherited it ignored (started in the
    # background by a non-interactive shell, as nohup and `cmd &` in scripts do).
    def on_signal(signum, frame):
        exp.request_stop(signal.Signals(signum).name)
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    try:
        outcome = exp.run()
    finally:
        # the run is recorded: a late signal (video, summary) only stops this program
        signal.signal(signal.SIGTERM, signal.default_int_handler)
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if cfg.record and getattr(exp, "snapshot_dir", None):
        try:
            video = assemble_video(exp.snapshot_dir, exp.prefix + "_run.mp4")
            if video:
                out(f"video: {video}")
        except PatrolInputError as e:
            out(f"warning: no video: {e}")
    return outcome


def print_summary(outcome, out=safe_print):
    info = read_info(outcome.prefix)
    rec = outcome.record or {}
    pace = f", pace {rec['pace']:.2f}x" if rec.get("pace") else ""
    out(f"result: {outcome.reason} (exit {outcome.exit_code}); sim {outcome.sim_time:.1f} s, "
        f"wall {outcome.wall_time:.1f} s{pace}"
        + (f", GO after {outcome.go_wall:.1f} s" if outcome.go_wall is not None else ""))
    culprit = rec.get("culprit") or {}
    for line in (culprit.get("log_tail") or [])[-5:]:
        out(f"  | {line}")
    if info and len(info) >= 22:
        def idl(x):
            return f"{x} s" if x else "-"
        out(f"summary: sim {info[10]} s, real {info[11]} s, cycles {info[21]}, visits "
            f"{info[19]}, idleness avg {idl(info[15])} / max {idl(info[17])}, interferences "
            f"{info[12]} ({info[18]}/min), end {info[13]}")
    line = scenario_summary(outcome.prefix)
    if line:
        out(line)
    record = f"{outcome.prefix}_run.yaml"
    where = f"in {record}" if os.path.isfile(record) else "no run record: it could not be written"
    out(f"results: {outcome.prefix}_* (status {outcome.status}, {where})")
    for f in outcome.files:
        out(f"  {f}")


def scenario_summary(prefix):
    """One line on the run's scenario from ``<prefix>_scenario.yaml`` (None without one):
    the model, each failure (s after GO) and the messages the receivers judged."""
    try:
        doc = read_scenario(prefix)
    except ValueError as e:
        return f"scenario: {e}"
    if not doc:
        return None
    fails = ", ".join(
        f"robot {f['robot']} at {f['t_fail']:g} s" +
        (f" (back at {f['t_repair']:g} s)" if f.get("t_repair") is not None else "")
        for f in doc.get("failures") or []) or "none"
    tot = (doc.get("counters") or {}).get("total") or {}
    sent = int(tot.get("sent", 0))
    msgs = (f"; messages sent {sent}, delivered {int(tot.get('delivered', 0))}, lost "
            f"{int(tot.get('lost', 0))} ({100.0 * int(tot.get('lost', 0)) / sent:.1f} %)"
            if sent else "")
    return f"scenario: comm {doc.get('comm')}; failures {fails}{msgs}"


def main(argv):
    args = build_parser().parse_args(argv)
    setup_logging()
    if args.batch:
        if args.positional or args.gui:
            raise PatrolInputError("argument --batch: cannot be combined with the positional "
                                   "form or --gui")
        if args.parallel < 1:
            raise PatrolInputError(f"argument --parallel: must be >= 1, got {args.parallel}")
        base = load_config_file(args.config) if args.config else ExperimentConfig()
        # flags given with --batch override every entry (as for --config)
        overrides = flag_overrides(args)
        configs = [c.updated(overrides, "command line") for c in load_batch(args.batch, base)]
        for k, c in enumerate(configs):
            try:
                if not args.dry_run:
                    c.check_environment()
                c.validate()
            except PatrolInputError as e:
                raise PatrolInputError(f"{args.batch}: entry {k + 1}: {e}") from None
        if args.dry_run:
            for k, c in enumerate(configs):
                print(f"run {k + 1}: " + " ".join(f"{key}={v}" for key, v in c.to_dict().items()))
            return 0
        got = []
        hold = SignalHold()

        def on_signal(signum, frame):
            got.append(signum)
            if hold.holding():                 # a run is being started: raise once it is
                hold.defer()                   # in the running table
                return
            raise KeyboardInterrupt
        old_term = signal.signal(signal.SIGTERM, on_signal)
        old_int = signal.signal(signal.SIGINT, on_signal)
        try:
            results = run_batch(configs, args.parallel, os.path.abspath(sys.argv[0]),
                                hold=hold)
        except BatchInterrupted as e:
            signal.signal(signal.SIGINT, signal.SIG_IGN)    # let the table be printed
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            print_batch_table(e.results)
            print("batch interrupted: runs with exit 130 were interrupted, '-' never started")
            return 143 if got and got[0] == signal.SIGTERM else 130
        finally:
            signal.signal(signal.SIGTERM, old_term)
            signal.signal(signal.SIGINT, old_int)
        print_batch_table(results)
        return 0 if all(r and r[1] == 0 for r in results) else 1
    no_config = not args.positional and not args.config and not any(
        getattr(args, k) is not None for k in FLAG_KEYS)
    if args.gui or (no_config and not args.headless):
        if not os.environ.get("DISPLAY"):
            raise PatrolInputError("no display for the GUI: give --headless with --map/--robots/"
                                   "--alg..., --config FILE, or the positional form")
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        return run_gui(os.path.abspath(sys.argv[0]),
                       load_config_file(args.config) if args.config else None)
    cfg = config_from_args(args)
    if not args.dry_run:
        cfg.check_environment()
    cfg.validate()
    if args.dry_run:
        exp = Experiment(cfg)
        prefix = exp.prepare()
        print(f"launch file: {exp.launch_path}")
        print(f"results: {prefix}_*")
        return 0
    outcome = run_one(cfg)
    print_summary(outcome)
    return outcome.exit_code


def entry():
    sys.exit(run_main(main, "start_experiments.py"))
