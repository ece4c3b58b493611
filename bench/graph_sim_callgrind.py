#!/usr/bin/python3
"""Load-independent cost of graph-mode runs: instructions executed, counted by valgrind's
callgrind. On a shared virtual machine the CPU time of the same graph-mode work swings by 20 %
and more from one minute to the next (bench/notes/graph_sim.md); an instruction count
does not, so a change of a few per cent in the simulator can be measured.

A fixed workload of reference-campaign cells (``--cells``, default: seven of them, small and
large maps, 4-12 robots, message-heavy and quiet algorithms; seed 0) runs in one Python process
under callgrind, through the campaign's worker function (simulation, files, metrics). A second
process does everything but the runs (imports, graphs, start vertices); the difference is the
runs' own count. Each run's visits and average idleness are printed too, so two versions of
the code can be checked to simulate the same thing.

    /usr/bin/python3 bench/graph_sim_callgrind.py                       # this checkout
    /usr/bin/python3 bench/graph_sim_callgrind.py --code /other/checkout --duration 600

About 3 minutes for the default workload (callgrind runs Python ~40x slower).
"""
import argparse
import json
import os
import re
import subprocess
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
DEFAULT_CELLS = ("1r5:12:DTAG,DIAG_labs:12:DTAP,cumberland:8:SEBS,grid:4:CR,broughton:12:CBLS,"
                 "move_base_arena:6:GBS,ctcv:12:HPCC")

CHILD = r"""
import json, os, sys
sys.path[:0] = [sys.argv[1], os.path.join(sys.argv[1], "..", "..", "spqrel_nav_lite", "src")]
from patrolling_sim.campaign.tasks import WorldCache, run_graph_task
from patrolling_sim.graphsim.config import GraphSimConfig
cells, duration, setup_only = json.loads(sys.argv[2]), float(sys.argv[3]), sys.argv[4] == "1"
worlds = WorldCache()
for m, n, a in cells:
    worlds.get(GraphSimConfig(map=m, robots=n, alg=a, seed=0, duration=duration))
out = []
if not setup_only:
    for m, n, a in cells:
        r = run_graph_task(dict(map=m, robots=n, alg=a, seed=0, duration=duration), worlds)
        out.append([m, n, a, r["status"], r["metrics"].get("total_visits"),
                    r["metrics"].get("idl_avg")])
print("RESULT " + json.dumps(out))
"""


def parse_cells(text):
    out = []
    for item in text.split(","):
        parts = item.strip().split(":")
        if len(parts) != 3 or not parts[1].isdigit():
            raise SystemExit(f"graph_sim_callgrind.py: --cells: '{item}' is not map:robots:alg")
        out.append([parts[0], int(parts[1]), parts[2]])
    return out


def instructions(code, cells, duration, setup_only):
    """(instructions collected, the child's per-run results)."""
    with tempfile.TemporaryDirectory(prefix="graph_cg_") as tmp:
        script = os.path.join(tmp, "child.py")
        with open(script, "w") as f:
            f.write(CHILD)
        env = dict(os.environ, PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))
        p = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                            "/usr/bin/python3", script, code, json.dumps(cells), str(duration),
                            "1" if setup_only else "0"],
                           capture_output=True, text=True, env=env, cwd=tmp)
    m = re.search(r"Collected : (\d+)", p.stderr)
    r = re.search(r"^RESULT (.*)$", p.stdout, re.M)
    if p.returncode != 0 or not m or not r:
        raise SystemExit(f"graph_sim_callgrind.py: the run under callgrind failed "
                         f"(exit {p.returncode}): {p.stderr.strip().splitlines()[-1:]}")
    return int(m.group(1)), json.loads(r.group(1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--code", default=os.path.join(ROOT, "src", "patrolling_sim", "src"),
                    help="folder holding the patrolling_sim package (default: this checkout's)")
    ap.add_argument("--cells", default=DEFAULT_CELLS, help="map:robots:alg,... (seed 0)")
    ap.add_argument("--duration", type=float, default=600.0, help="sim seconds per run")
    a = ap.parse_args(argv)
    if not os.path.isdir(os.path.join(a.code, "patrolling_sim")):
        raise SystemExit(f"graph_sim_callgrind.py: --code: no patrolling_sim package in {a.code}")
    if a.duration <= 0:
        raise SystemExit("graph_sim_callgrind.py: --duration must be > 0")
    cells = parse_cells(a.cells)
    full, runs = instructions(a.code, cells, a.duration, False)
    base, _ = instructions(a.code, cells, a.duration, True)
    print(f"code: {a.code}")
    print("| map | robots | alg | status | visits | avg idleness (s) |")
    print("|---|---|---|---|---|---|")
    for m, n, alg, status, visits, idl in runs:
        print(f"| {m} | {n} | {alg} | {status} | {visits:g} | {idl} |")
    print(f"\ninstructions: {full / 1e9:.3f} G in all, {base / 1e9:.3f} G without the runs: "
          f"**{(full - base) / 1e9:.3f} G for the {len(cells)} runs of {a.duration:g} s**")


if __name__ == "__main__":
    main()
