"""Lint and the API reference build, run by `make test` (also `make lint`, `make docs`):
flake8 reports nothing under .flake8's configuration, and Sphinx builds the API reference
from the docstrings without a single warning."""
import glob
import os
import subprocess
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def test_flake8_reports_nothing():
    nodes = sorted(glob.glob(os.path.join(ROOT, "src", "*", "nodes", "*")))
    r = subprocess.run([sys.executable, "-m", "flake8", "src", "scripts", "bench", "tests"]
                       + [n for n in nodes if os.path.isfile(n)],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, (r.stdout + r.stderr)[-5000:]


def test_api_reference_builds_without_warnings(tmp_path):
    r = subprocess.run(["bash", os.path.join(ROOT, "scripts", "build_api_docs.sh"),
                        str(tmp_path / "html")], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, (r.stdout + r.stderr)[-5000:]
    assert (tmp_path / "html" / "modules" / "patrolling_sim.model.graph.html").exists()
