"""Start-up signal handling shared by the command-line scripts (imported first, before any
heavy module, so it must stay tiny): a SIGINT / SIGTERM while the program is still loading
ends it at once with one line and the shell's exit code (130 / 143). Nothing has been
started or written yet; the program installs its own handlers later.

A parent that must not lose a signal sent during the child's interpreter start (before these
handlers exist, Python would raise KeyboardInterrupt somewhere in its start-up and exit 1
with a traceback) starts the child with SIGINT and SIGTERM blocked
(``patrolling_sim.runner.batch.spawn_with_signals_held``): a signal sent meanwhile stays
pending, and :func:`install` unblocks it once the handlers are in place."""
import os
import sys
# the interpreter's own signal module (built in, already loaded): the ``signal`` wrapper
# would first import ``enum``, which widens the window before the handlers exist
import _signal

#: names of the signals handled here (``signal.Signals`` would need ``enum``)
_NAMES = {_signal.SIGINT: "SIGINT", _signal.SIGTERM: "SIGTERM"}


def install(program):
    """Install the early handlers for ``program`` (its name in the message). Also when
    SIGINT was inherited ignored (``cmd &`` in a script)."""
    def handler(signum, frame):
        sys.stderr.write(f"{program}: interrupted by {_NAMES[signum]} before "
                         "the run started\n")
        sys.stderr.flush()
        os._exit(143 if signum == _signal.SIGTERM else 130)
    _signal.signal(_signal.SIGINT, handler)
    _signal.signal(_signal.SIGTERM, handler)
    # delivered now if it came while blocked by the parent (see the module docstring)
    _signal.pthread_sigmask(_signal.SIG_UNBLOCK, {_signal.SIGINT, _signal.SIGTERM})


def require(program, modules=()):
    """Exit at once with one line and status 2 unless this interpreter can import the
    workspace's packages and ``modules`` (e.g. ``("rospy",)`` for the ROS runner): nothing
    has been started yet. The packages come from the workspace's environment
    (``source devel/setup.bash``, or an install space's ``setup.bash``)."""
    import importlib.util
    if importlib.util.find_spec("patrolling_sim") is None:
        _refuse(f"{program}: the patrolling_sim package is not on this Python's path: run "
                "`source devel/setup.bash` (after `make setup`) first")
    for module in modules:
        if importlib.util.find_spec(module) is None:
            _refuse(f"{program}: this Python ({sys.executable}) cannot import {module}: run "
                    f"with /usr/bin/python3 (Debian's, which has it), e.g. "
                    f"`/usr/bin/python3 {sys.argv[0]} ...`")


def _refuse(line):
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
    os._exit(2)
