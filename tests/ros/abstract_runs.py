"""Run our agents + monitor in the abstract world through the runner
(``scripts/start_experiments.py --nav abstract``, docs/abstract_world.md) and read the
figures the fidelity comparison uses. Shared by tests/ros/test_abstract_fidelity.py and
bench/fidelity_ros.py."""
import glob
import os
import re
import statistics
import subprocess
import sys
from dataclasses import dataclass

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from rosenv import ros_env  # noqa: E402

#: the reference runs' world: grid, 4 robots at vertices 0, 13, 20, 11 (the grid_4 default
#: poses), 600 sim s after GO
MAP, ROBOTS, DURATION = "grid", 4, 600.0
#: pace of the abstract world: fast, and slow enough that the agents' turnaround stays close
#: to the reference runs' (docs/abstract_world.md, "Turnaround and pace")
SPEEDUP = 30.0
#: generous safety net against a hung run (x30: ~20 s of sim, ~30 s with start and stop);
#: results are judged on sim-time figures only
RUN_LIMIT = 900.0

_TURN = re.compile(r"turnaround SUCCEEDED->next goal \(sim s\): n (\d+) mean ([0-9.]+)")


@dataclass
class AbstractRun:
    exit_code: int
    output: str
    prefix: str = None
    info: dict = None
    avg: float = None           # mean of the idleness samples (as the reference table)
    max: float = None           # info.csv max idleness
    visits: int = None          # info.csv total visits
    turnaround: float = None    # world's mean SUCCEEDED -> next goal, sim s

    def figures(self):
        return (self.avg, self.max, self.visits)

    def complete(self, duration=DURATION):
        """The run ended on its timeout after ``duration`` sim s (its figures are usable)."""
        return (self.info is not None and self.info["termination"] == "TIMEOUT"
                and self.info["sim_duration"] >= duration)


def run_abstract(alg, seed, results_dir, processes="shared", speedup=SPEEDUP,
                 duration=DURATION, extra=(), map_name=MAP, robots=ROBOTS):
    """One run of ``alg`` in the abstract world (``map_name``, ``robots`` at their default
    start positions) at ``speedup`` (None: the runner's default, auto); returns an
    :class:`AbstractRun` (figures None when the run wrote no info.csv)."""
    pace = [] if speedup is None else ["--speedup", f"{speedup:g}"]
    cmd = ["/usr/bin/python3", START, "--headless", "--map", map_name, "--robots", str(robots),
           "--alg", alg, "--nav", "abstract", "--timeout", f"{duration:g}", *pace,
           "--seed", str(seed), "--processes", processes, "--results-dir",
           str(results_dir), *extra]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          env=ros_env(), cwd=str(results_dir), timeout=RUN_LIMIT,
                          start_new_session=True)
    return read_results(AbstractRun(proc.returncode, proc.stdout), results_dir)


def read_results(run, results_dir):
    """``run`` (an :class:`AbstractRun`) with the prefix, info, figures and turnaround of the
    one run whose files are under ``results_dir``; left None without exactly one info.csv."""
    from patrolling_sim.report.loading import load_run
    infos = glob.glob(os.path.join(str(results_dir), "**", "*_info.csv"), recursive=True)
    if len(infos) != 1:
        return run
    run.prefix = infos[0][:-len("_info.csv")]
    loaded = load_run(run.prefix)
    run.info = loaded.info
    run.avg = float(loaded.samples["Idleness"].mean()) if len(loaded.samples) else None
    run.max = loaded.info["idl_max"]
    run.visits = loaded.info["total_visits"]
    for log in glob.glob(run.prefix + "_logs/*/abstract_world-*-stdout.log"):
        with open(log, encoding="utf-8") as f:
            m = _TURN.search(f.read())
        if m:
            run.turnaround = float(m.group(2))
    return run


def mean_figures(runs):
    """(avg, max, visits) averaged over runs [(avg, max, visits)]."""
    return tuple(statistics.mean(r[k] for r in runs) for k in range(3))
