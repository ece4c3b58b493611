"""Track and stop one process tree, and nothing else.

roslaunch starts every node in a session of its own (``os.setsid``), so killing
roslaunch's process group does not reach the nodes. :class:`ProcessTree` remembers every
descendant of a root pid it has seen (pid plus start time, so a recycled pid is never
signalled) and can stop the survivors. It never looks processes up by name.
"""
import os
import signal
import time
from typing import NamedTuple, Optional


class ProcStat(NamedTuple):
    """The fields of ``/proc/<pid>/stat`` this project reads."""
    state: str          # "R", "S", ..., "Z" for a zombie
    ppid: int
    pgrp: int           # process group id
    starttime: int      # clock ticks since boot: with the pid, identifies the process


def proc_stat(pid) -> Optional[ProcStat]:
    """:class:`ProcStat` of a process, or None if it is gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            data = f.read().decode(errors="replace")
    except OSError:
        return None
    # the command name may contain spaces and parentheses: split after the last ')'
    rest = data[data.rfind(")") + 2:].split()
    try:
        return ProcStat(rest[0], int(rest[1]), int(rest[2]), int(rest[19]))
    except (IndexError, ValueError):
        return None


def _children_map():
    kids = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        st = proc_stat(int(name))
        if st:
            kids.setdefault(st.ppid, []).append(int(name))
    return kids


def proc_label(pid) -> Optional[str]:
    """A short name for a process, for messages: a ROS node's name (its ``__name:=``
    argument), else the program (for an interpreter, the script it runs); None if the
    process is gone."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = [a.decode(errors="replace") for a in f.read().split(b"\0") if a]
    except OSError:
        return None
    for a in argv:
        if a.startswith("__name:="):
            return a[len("__name:="):]
    if not argv:
        return None
    prog = os.path.basename(argv[0])
    if prog.startswith("python") and len(argv) > 1:
        prog = os.path.basename(argv[1])
    return prog


class ProcessTree:
    """The descendants of one root process seen so far (see the module docstring)."""

    def __init__(self, root_pid):
        self.root = root_pid
        self.known = {}     # pid -> starttime
        self.labels = {}    # pid -> proc_label, read when the process was first seen
        self.refresh()

    def refresh(self):
        """Record the current descendants of the root (and the root)."""
        kids = _children_map()
        stack = [self.root]
        while stack:
            pid = stack.pop()
            st = proc_stat(pid)
            if st is None:
                continue
            if pid not in self.known:
                self.known[pid] = st.starttime
                self.labels[pid] = proc_label(pid) or "?"
            stack.extend(kids.get(pid, []))

    def alive(self):
        """Known processes still running (same pid and start time)."""
        out = []
        for pid, start in self.known.items():
            st = proc_stat(pid)
            # a zombie is already dead, waiting to be reaped
            if st is not None and st.starttime == start and st.state != "Z":
                out.append(pid)
        return out

    def describe(self, pids) -> str:
        """``"roslaunch (pid 12), monitor (pid 40)"``: the known processes ``pids``."""
        return ", ".join(f"{self.labels.get(p, '?')} (pid {p})" for p in pids)

    def signal_all(self, sig):
        for pid in self.alive():
            try:
                os.kill(pid, sig)
            except OSError:
                pass

    def stop(self, grace=10.0, term_wait=3.0):
        """SIGINT, then (``grace`` s later) SIGTERM, then (``term_wait`` s later) SIGKILL the
        survivors; returns the pids killed hard."""
        self.refresh()
        for sig, wait in ((signal.SIGINT, grace), (signal.SIGTERM, term_wait),
                          (signal.SIGKILL, 2.0)):
            if not self.alive():
                return []
            hard = self.alive() if sig == signal.SIGKILL else []
            self.signal_all(sig)
            deadline = time.monotonic() + wait
            while time.monotonic() < deadline and self.alive():
                time.sleep(0.1)
            if hard:
                return hard
        return []
