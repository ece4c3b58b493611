"""pytest configuration: make the workspace's pure-Python packages importable without
sourcing devel/setup.bash, and share fixtures."""
import os
import signal
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for pkg in ("patrolling_sim", "spqrel_nav_lite"):
    p = os.path.join(ROOT, "src", pkg, "src")
    if p not in sys.path:
        sys.path.insert(0, p)


# --- processes the tests started in groups of their own (tests/process_guard.py) ---------
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import process_guard  # noqa: E402


def _sigterm_as_ctrl_c(signum, frame):
    raise KeyboardInterrupt(f"pytest received {signal.Signals(signum).name}")


def pytest_configure(config):
    process_guard.install()
    # a CI timeout's SIGTERM ends pytest as Ctrl-C does: teardown and sessionfinish run
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _sigterm_as_ctrl_c)


def pytest_sessionfinish(session, exitstatus):
    stopped = process_guard.stop_leftovers()
    if stopped:
        lines = [f"group {g}: pids {', '.join(map(str, sorted(p)))}"
                 for g, p in sorted(stopped.items())]
        rep = session.config.pluginmanager.get_plugin("terminalreporter")
        msg = (f"process guard: stopped {len(stopped)} process group(s) that tests had started "
               f"and left running ({'; '.join(lines)})")
        if rep is not None:
            rep.write_line(msg, yellow=True)
        else:
            sys.stderr.write(msg + "\n")
