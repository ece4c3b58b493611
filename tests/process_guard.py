"""Leftover processes of a test session.

Many tests start an experiment, a ROS master or a simulator in a session (or process group)
of its own, so that they can stop all of it with one ``killpg``. If the test session itself
is stopped (Ctrl-C, a CI timeout's SIGTERM) while such a test runs, the test's own clean-up
may never run and the experiment outlives pytest, still holding ports, CPU and files.

This module records the process group of every ``subprocess.Popen`` started with
``start_new_session=True`` or ``process_group=0`` during the session
(:func:`install`), and :func:`stop_leftovers`, called when the session ends, stops whatever
is still running in those groups: SIGTERM to the group (a runner then writes its files and
stops its own children), SIGKILL after a grace period. Only groups this session started are
touched, by their id, never processes found by name. ``tests/conftest.py`` wires it in and
also turns SIGTERM into Ctrl-C, so that pytest's teardown (and this clean-up) runs.

Linux keeps a process id allocated while it is still used as the id of a group, so a group id
recorded here cannot be reused by an unrelated group while any member of ours is alive; a
leader that is still alive is compared by its start time as well.
"""
import os
import signal
import subprocess
import time
from typing import Dict, List, Optional

from patrolling_sim.runner.proctree import proc_stat

#: process group id -> start time (clock ticks since boot) of the process that leads it
_started: Dict[int, int] = {}
#: s to wait for SIGKILLed processes to be gone (they take milliseconds; a bound, no more)
KILL_WAIT = 30.0
_installed = False


def record(pid: int) -> None:
    """Remember the group led by ``pid`` (a process just started in a group of its own)."""
    st = proc_stat(pid)
    if st is not None:
        _started[pid] = st.starttime


class _RecordingPopen(subprocess.Popen):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if kwargs.get("start_new_session") or kwargs.get("process_group") == 0:
            record(self.pid)


def install() -> None:
    """Record the groups of the session's new-session / new-group subprocesses from now on
    (``subprocess.run`` and ``Popen`` both go through ``subprocess.Popen``)."""
    global _installed
    if not _installed:
        subprocess.Popen = _RecordingPopen
        _installed = True


def members(pgid: int, leader_start: Optional[int] = None) -> List[int]:
    """Live (not zombie) processes of the group ``pgid``; none if its leader is alive but is
    not the process recorded (its start time differs)."""
    if leader_start is not None:
        lead = proc_stat(pgid)
        if lead is not None and lead.pgrp == pgid and lead.starttime != leader_start:
            return []
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            st = proc_stat(int(d))
            if st is not None and st.pgrp == pgid and st.state != "Z":
                out.append(int(d))
    return out


def stop_groups(groups: Dict[int, int], grace: float = 15.0) -> Dict[int, List[int]]:
    """Stop every process still in one of ``groups`` (group id -> leader start time):
    SIGTERM to each group, SIGKILL to those still alive after ``grace`` seconds; returns once
    they are gone (SIGKILL is delivered asynchronously: a killed process is still listed for a
    moment), or after ``KILL_WAIT`` s. Returns the groups that had processes, with the ids
    found."""
    found = {g: members(g, t) for g, t in groups.items()}
    found = {g: pids for g, pids in found.items() if pids}

    def signal_and_wait(sig, wait):
        for g in found:
            if members(g, groups[g]):
                try:
                    os.killpg(g, sig)
                except OSError:
                    pass
        end = time.monotonic() + wait
        while time.monotonic() < end and any(members(g, groups[g]) for g in found):
            time.sleep(0.05)
    try:
        signal_and_wait(signal.SIGTERM, grace)
    except KeyboardInterrupt:
        # a second interrupt (Ctrl-C again, or a pytest-xdist worker's SIGINT from execnet
        # while its session finishes) cuts the grace short: SIGKILL now, not never
        pass
    previous = _ignore_sigint()
    try:
        signal_and_wait(signal.SIGKILL, KILL_WAIT)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    return found


def _ignore_sigint():
    """Ignore SIGINT (in the main thread only; elsewhere it cannot arrive as an exception)
    while the SIGKILLs go out; returns the handler to restore, or None."""
    import threading
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGINT, signal.SIG_IGN)


def stop_leftovers(grace: float = 15.0) -> Dict[int, List[int]]:
    """:func:`stop_groups` over every group recorded this session; forgets them."""
    groups = dict(_started)
    _started.clear()
    return stop_groups(groups, grace)
