"""The learning environment's tests (patrolling_sim.envs) import gymnasium and pettingzoo,
which Debian 12 does not package: scripts/setup.sh installs them into .venv/ (from
scripts/requirements-learning.txt). This conftest appends that venv's site-packages to the
END of sys.path, so that wherever Debian and the venv both have a package, Debian's is the one
imported; only modules Debian lacks come from the venv (docs/development.md)."""
import glob
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
for site in sorted(glob.glob(os.path.join(ROOT, ".venv", "lib", "python3*", "site-packages"))):
    if site not in sys.path:
        sys.path.append(site)
try:
    import gymnasium  # noqa: F401
    import pettingzoo  # noqa: F401
except ImportError as e:
    raise ImportError(f"{e}: the learning environment's tests need gymnasium and pettingzoo "
                      "in .venv/; run `make setup` (scripts/setup.sh installs "
                      "scripts/requirements-learning.txt)") from None
