"""The ORIGINAL patrolling_sim's own C++ agents, unchanged, on both of this project's worlds:
the abstract world and the full stack (the Box2D simulator and this project's navigation),
with this project's monitor (bench/original_agents.py). Their topic API is the original's,
so nothing in the worlds may need them to change: each run must end on its timeout with
every vertex visited.

The original's agents are not part of this repository (docs/fidelity.md, "The original's own
agents in the abstract world", says how to build them), so these tests run only where
``PATROLLING_SIM_ORIGINAL_WS`` names a catkin workspace in which they are built, and are
skipped otherwise (as in CI)."""
import csv
import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(HERE, ".."))
from rosenv import ros_env  # noqa: E402

WS = os.environ.get("PATROLLING_SIM_ORIGINAL_WS", "")
pytestmark = pytest.mark.skipif(
    not WS or not os.path.isfile(os.path.join(WS, "devel", "setup.bash")),
    reason="PATROLLING_SIM_ORIGINAL_WS does not name a built workspace of the original")

#: (world arguments, pace): the abstract world fast, the full stack at a pace two cores hold
WORLDS = {"abstract": (["--nav", "abstract"], 20),
          "full_stack": (["--nav", "spqrel_nav_lite", "--loc", "fake_localization"], 3)}
#: a message-passing algorithm and one without messages
ALGS = ("SEBS", "CGG")
DURATION = 120


@pytest.mark.parametrize("world", sorted(WORLDS))
@pytest.mark.parametrize("alg", ALGS)
def test_the_original_s_agents_patrol_unchanged(alg, world, tmp_path):
    args, pace = WORLDS[world]
    summary = tmp_path / "runs.csv"
    cmd = ["/usr/bin/python3", os.path.join(ROOT, "bench", "original_agents.py"),
           "--orig-ws", WS, "--alg", alg, "--map", "grid", "--robots", "4",
           "--duration", str(DURATION), "--runs", "1", "--speedup", str(pace),
           "--out", str(tmp_path / "run"), "--summary", str(summary), *args]
    r = subprocess.run(cmd, env=ros_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True, timeout=900)
    assert r.returncode == 0, r.stdout[-3000:]
    rows = list(csv.DictReader(open(summary, newline="", encoding="utf-8")))
    assert len(rows) == 1, r.stdout[-3000:]
    row = rows[0]
    assert row["termination"] == "TIMEOUT" and float(row["sim_duration"]) >= DURATION, row
    assert row["agents_exited"] == "", f"an agent's process ended early: {row}"
    counts = [int(c) for c in row["visit_counts"].split()]
    assert len(counts) == 25 and min(counts) > 0, f"a vertex was never visited: {counts}"
