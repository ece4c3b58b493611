"""``scripts/report.py RESULTS_DIR... --out OUT_DIR [--title T]`` (see docs/report.md)."""
import logging
import sys

from patrolling_sim.common.cli import CliParser, run_main, setup_logging
from patrolling_sim.report.build import build_report

PROG = "report.py"


def parser():
    ap = CliParser(prog=PROG, description=(
        "Analyse patrolling results: find every *_info.csv under the given directories "
        "(ROS mode and graph mode alike), and write report.html (self-contained), "
        "summary.csv, runs.csv, pairwise_pvalues.csv and PNG figures into OUT_DIR."))
    ap.add_argument("dirs", nargs="+", metavar="RESULTS_DIR",
                    help="results folder(s) (searched recursively) or *_info.csv files")
    ap.add_argument("--out", required=True, metavar="OUT_DIR", help="output folder (created)")
    ap.add_argument("--title", default=None, help="report title")
    ap.add_argument("--no-run-plots", action="store_true",
                    help="skip the per-run idleness-over-time figures (large batches)")
    ap.add_argument("--include-fail", action="store_true",
                    help="also average runs that ended with FAIL (a robot declared dead); "
                         "runs that were interrupted, crashed or aborted are never averaged")
    ap.add_argument("-q", "--quiet", action="store_true", help="no warnings, no summary")
    return ap


def main(argv):
    args = parser().parse_args(argv)
    if args.title is not None and not args.title.strip():
        parser().error("argument --title: empty title")
    setup_logging()
    logging.getLogger("matplotlib").setLevel(logging.WARNING)
    res = build_report(args.dirs, args.out, args.title, run_plots=not args.no_run_plots,
                       include_fail=args.include_fail)
    if not args.quiet:
        for w in res["warnings"]:
            sys.stderr.write(f"{PROG}: warning: {w}\n")
        for _, e in res["excluded"].iterrows():
            sys.stderr.write(f"{PROG}: excluded: {e['run_id']}: {e['why']}\n")
        for _, g in res["summary"].iterrows():
            print(f"  {g['map']} N={g['N']} {g['algorithm']}: {g['runs']} used; statuses "
                  f"{g['statuses']}")
        print(f"{res['runs']} run(s) used, {len(res['excluded'])} excluded, "
              f"{len(res['summary'])} group(s); report: {res['files'][0]}")
    return 0


def entry():
    logging.captureWarnings(True)
    sys.exit(run_main(main, PROG))
