"""The ``campaign.py`` command line: validate a campaign file, list its runs (``--dry-run``)
or run what is left of it (:func:`patrolling_sim.campaign.engine.run_campaign`), then print
its table and write its HTML report. See docs/campaigns.md."""
import os
import signal
import sys

from patrolling_sim.campaign.cluster import env_for_workers
from patrolling_sim.campaign.engine import run_campaign
from patrolling_sim.campaign.folder import hold_folder
from patrolling_sim.campaign.spec import RESULTS_DIR, load_campaign
from patrolling_sim.campaign.store import load_state, needs_run, summary_table
from patrolling_sim.common import paths
from patrolling_sim.common.cli import CliParser
from patrolling_sim.common.cli import run_main
from patrolling_sim.common.errors import PatrolInputError

#: a campaign's report draws one idleness-over-time figure per run only up to this many
#: runs (each is a PNG of ~0.2 s; the reference campaign has 7020 runs)
REPORT_RUN_PLOTS_MAX = 200


def build_parser():
    """The argument parser of ``campaign.py`` (a :class:`CliParser`: one-line errors,
    exit status 2)."""
    ap = CliParser(prog="campaign.py", description=(
        "Run a campaign (a grid of experiments, graph or ROS mode) on Dask: a LocalCluster "
        "on this machine by default, or an existing cluster with --scheduler. Re-running "
        "the same command resumes (finished runs are skipped)."))
    ap.add_argument("campaign", help="campaign file (YAML)")
    ap.add_argument("--out", help="campaign folder (default: results/campaigns/<name>)")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler")
    ap.add_argument("--workers", type=int, help="LocalCluster size (default: the cores for "
                    "graph mode, half of them for ROS mode)")
    ap.add_argument("--retry-failed", action="store_true", help="redo crashed runs too")
    ap.add_argument("--limit", type=int, help="run at most this many runs now")
    ap.add_argument("--dry-run", action="store_true",
                    help="validate and list the runs, run nothing")
    ap.add_argument("--no-report", action="store_true", help="skip the HTML report")
    ap.add_argument("--force-new", action="store_true",
                    help="start this campaign in an --out folder that holds another one (its "
                    "table and report then use only this campaign's own runs)")
    return ap


def parse_args(args):
    """The parsed command line ``args`` (a list of strings); a bad value ends the program
    with a one-line error and exit status 2."""
    ap = build_parser()
    a = ap.parse_args(args)
    if a.workers is not None and a.workers < 1:
        ap.error(f"argument --workers: must be >= 1, got {a.workers}")
    if a.limit is not None and a.limit < 1:
        ap.error(f"argument --limit: must be >= 1, got {a.limit}")
    return a


def print_dry_run(camp, out, retry_failed):
    """Print one line per run of ``camp``: its key, ``run`` (it would run now, given the
    state records in the campaign folder ``out``, if any) or ``done``, and its label."""
    state = load_state(out) if os.path.isdir(out) else {}
    for r in camp.runs:
        todo = needs_run(state.get(r.key), retry_failed)
        print(f"{r.key}  {'run ' if todo else 'done'}  {r.label()}")


def own_result_sets(camp, out, state):
    """The result files of ``camp``'s own runs in the folder ``out``, from their records in
    ``state`` (by run key): each run's info file, or its ``_run.yaml`` when it has none (the
    report lists such runs). Never what else lies in the folder."""
    sets = []
    for r in camp.runs:
        prefix = (state.get(r.key) or {}).get("prefix")
        if not prefix:
            continue
        base = os.path.join(out, prefix)
        for suffix in ("_info.csv", "_run.yaml"):
            if os.path.isfile(base + suffix):
                sets.append(base + suffix)
                break
    return sets


def write_report(camp, out, state):
    """Write the HTML report of ``camp``'s own runs in the folder ``out`` (their records in
    ``state``, :func:`own_result_sets`) into ``out/report`` and print its path; per-run time
    plots only up to REPORT_RUN_PLOTS_MAX runs. Never raises on a report error: the table
    is the product, so the error is printed as a warning and an older report is removed."""
    per_run = len(camp.runs) <= REPORT_RUN_PLOTS_MAX
    page = os.path.join(out, "report", "report.html")
    try:
        # deferred: the report layer imports pandas and matplotlib (about 1 s), which a
        # campaign command needs only when it writes its report
        from patrolling_sim.report.build import build_report
        sets = own_result_sets(camp, out, state)
        if not sets:
            raise PatrolInputError("no run of this campaign has result files")
        build_report(sets, os.path.join(out, "report"), run_plots=per_run)
        print(f"report: {os.path.join(out, 'report', 'report.html')}"
              + ("" if per_run else f" (no per-run time plots: {len(camp.runs)} runs "
                 f"> {REPORT_RUN_PLOTS_MAX}; scripts/report.py "
                 f"{os.path.join(out, RESULTS_DIR)} draws them)"))
    except Exception as e:             # the table is the product; say why no report
        if os.path.isfile(page):       # never leave a report of other runs in place
            os.remove(page)
        print(f"campaign.py: warning: no report ({type(e).__name__}: {e})")


def run_command(args):
    """``campaign.py`` with the command line ``args``; returns its exit status (0; 130 or
    143 when a SIGINT or SIGTERM interrupted the campaign). Raises PatrolInputError on a
    bad campaign file (turned into a one-line error by :func:`main`)."""
    a = parse_args(args)
    if not a.scheduler and not a.dry_run and os.path.isfile(a.campaign):
        # a LocalCluster is likely: its workers' forkserver starts importing now, on the
        # other core, while this process imports the simulator to validate the campaign
        # (if the file turns out to be bad, or nothing is left to run, the server just
        # exits with this process)
        env_for_workers()
    camp = load_campaign(a.campaign)
    for line in camp.warnings:
        sys.stderr.write(f"campaign.py: warning: {line}\n")
    out = a.out or os.path.join(paths.results_root(), "results", "campaigns", camp.name)
    if a.dry_run:
        print_dry_run(camp, out, a.retry_failed)
        return 0
    with hold_folder(out, camp, a.force_new):
        res = run_campaign(camp, out, scheduler=a.scheduler, workers=a.workers,
                           retry_failed=a.retry_failed, limit=a.limit)
        print(summary_table(out))
        if res["redone"]:
            print(f"redone: {res['redone']} finished run(s) whose files were missing or "
                  "damaged")
        print(f"table: {res['table']}")
        if not a.no_report and not res["interrupted"] and os.path.isdir(
                os.path.join(out, RESULTS_DIR)):
            write_report(camp, out, res["state"])
    if res["interrupted"]:
        return 130 if res["signal"] == signal.SIGINT else 143
    return 0


def main(argv=None):
    """Entry point of ``scripts/campaign.py``: :func:`run_command` on ``argv`` (None: the
    process's arguments) with the project's error handling
    (:func:`patrolling_sim.common.cli.run_main`); returns the exit status."""
    return run_main(run_command, "campaign.py", argv)
