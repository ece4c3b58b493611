"""pytest configuration: make the workspace's pure-Python packages importable without
sourcing devel/setup.bash, and share fixtures."""
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for pkg in ("patrolling_sim", "spqrel_nav_lite"):
    p = os.path.join(ROOT, "src", pkg, "src")
    if p not in sys.path:
        sys.path.insert(0, p)
