"""Deciding how a supervised experiment ended: which status (run_status.STATUSES), why,
which node is to blame, and the timing figures, from what the runner saw (a stop request,
a node's death, its own abort reason) and what the monitor wrote (info.csv,
``<prefix>_run.yaml``). Pure functions: no process, no ROS (docs/architecture.md,
"runner"; docs/monitor.md for the statuses)."""
import os
from dataclasses import dataclass, field

from patrolling_sim.common.errors import NoSpaceError, free_bytes
from patrolling_sim.monitor import run_status as rs
from patrolling_sim.runner.roslaunch_log import describe_node, is_monitor

RESULT_SUFFIXES = ("idleness.csv", "timeresults.csv", "results.txt", "info.csv")


@dataclass
class Outcome:
    exit_code: int
    reason: str
    prefix: str = ""
    files: list = field(default_factory=list)
    sim_time: float = 0.0
    wall_time: float = 0.0
    go_wall: float = None      # wall seconds from launch to GO
    status: str = ""           # run_status.STATUSES
    record: dict = field(default_factory=dict)   # the content of <prefix>_run.yaml


def read_info(prefix):
    """Fields of ``<prefix>_info.csv`` (list of str) or None."""
    try:
        with open(prefix + "_info.csv", encoding="utf-8") as f:
            line = f.readline().strip()
    except OSError:
        return None
    return line.split(";") if line else None


def signal_name(reason):
    """"SIGINT" / "SIGTERM" if the stop reason is a signal, else None."""
    return reason if reason in ("SIGINT", "SIGTERM") else None


def late_crash(deaths, ended):
    """The death that roslaunch reported while it ended which makes the run CRASHED
    (a launch error, a node other than the monitor failing before END, or the monitor
    failing), or None."""
    for d in deaths:
        monitor = is_monitor(d)
        if d["launch_error"] or (not monitor and d["exit_code"] not in (0, None)
                                 and not ended):
            return d
        if monitor and d["exit_code"] not in (0, None):
            return d
    return None


def _culprit(node, description, robot=None, exit_code=None, log=None):
    return {"node": node, "description": description, "robot": robot,
            "exit_code": exit_code, "log": log, "log_tail": rs.log_tail(log) if log else []}


def _crash_record(crash):
    desc, rid = describe_node(crash["node"])
    code = crash["exit_code"]
    if crash["launch_error"]:
        why = f"roslaunch could not start {desc} ({crash.get('message', '')})"
    else:
        why = (f"{desc} died (exit {code})" if code not in (0, None) else
               f"{desc} exited before the end of the run" if code == 0 else
               f"{desc} died")
    return {"status": rs.CRASHED, "reason": why,
            "culprit": _culprit(crash["node"], desc, rid, code, crash["log"])}


def decide_status(stop, crash, abort_reason, info, monitor_record):
    """The run's record (status, reason, culprit, robots, signal), first cause first: a
    signal, a stop request, a node's death, the runner's abort, a missing info.csv, the
    monitor's own verdict, else roslaunch ended it unexplained."""
    sig = signal_name(stop)
    record = {"status": None, "reason": "", "culprit": None, "robots": [], "signal": None}
    monitor_status = rs.normalise(info[13]) if info and len(info) > 13 else None
    if monitor_status == rs.INTERRUPTED:
        monitor_status = None       # the monitor was stopped from outside: not its verdict
    if sig:
        record.update(status=rs.INTERRUPTED, signal=sig, reason=f"interrupted by {sig}")
    elif stop:
        record.update(status=rs.ABORTED, reason=stop)
    elif crash is not None:
        record.update(_crash_record(crash))
    elif abort_reason:
        record.update(status=rs.ABORTED, reason=abort_reason)
    elif info is None:
        record.update(status=rs.CRASHED, reason="the monitor ended without writing "
                      "info.csv (see the logs)", culprit=_culprit("monitor", "the monitor"))
    elif monitor_status:
        record.update(status=monitor_status, reason=monitor_record.get("reason") or
                      f"ended: {monitor_status}", robots=monitor_record.get("robots") or [])
    else:
        record.update(status=rs.CRASHED, reason="roslaunch ended the run without a node "
                      "reporting its death (see roslaunch.log)",
                      culprit=_culprit("roslaunch", "roslaunch"))
    return record


def _info_float(info, i):
    if info is not None and len(info) > i:
        try:
            return float(info[i])
        except ValueError:
            return None
    return None


def timing(info, watcher, go_wall, wall):
    """(sim seconds since GO or None, wall seconds since GO or None, pace or None): the
    monitor's own figures if it wrote them, else what the runner saw."""
    sim = _info_float(info, 10)
    if sim is None and watcher is not None and watcher.sim_at_go is not None:
        sim = max(0.0, watcher.sim_time - watcher.sim_at_go)
    real = _info_float(info, 11)
    if not real and go_wall is not None:
        real = wall - go_wall
    pace = sim / real if sim and real and real > 0 else None
    return sim, real, pace


#: status fields of the clock holds, by record field: the abstract world's names first, then
#: the Box2D simulator's (steps that waited for the controllers' commands, waits that timed
#: out)
CLOCK_FIELDS = {"holds": ("clock_holds", "sync_waits"),
                "hold_timeouts": ("hold_timeouts", "sync_timeouts"),
                "held_wall": ("held_wall",)}


def clock_record(status, requested, achieved):
    """The run record's ``clock``: the pace requested (``--speedup``) and achieved (sim /
    wall s since GO), and from the simulator's last status (``status``, a dict; empty if
    none came) how often it held the clock to wait for the agents, how many of those waits
    reached their bound, the wall s held and the per-reason figures; a figure the simulator
    does not report is None."""
    rec = {"pace_requested": requested,
           "pace_achieved": round(achieved, 2) if achieved else None}
    for field_name, keys in CLOCK_FIELDS.items():
        rec[field_name] = next((status[k] for k in keys if k in status), None)
    if isinstance(status.get("hold_reasons"), dict):
        rec["reasons"] = status["hold_reasons"]
    return rec


def missing_files(prefix):
    """Names of the result files the run did not write."""
    return [f"{os.path.basename(prefix)}_{s}" for s in RESULT_SUFFIXES
            if not os.path.isfile(f"{prefix}_{s}")]


def summary(status, record, dead_robot_timeout):
    """The one-line reason shown to the user."""
    why = f"{status}: {record['reason']}" if record["reason"] and \
        record["reason"] != f"ended: {status}" else status
    if status == rs.FAIL and record["robots"]:
        why = f"FAIL: robot(s) {', '.join(map(str, record['robots']))} sent no visit for " \
              f"{dead_robot_timeout:g} sim s"
    return why


#: bytes: a run that failed while its results' file system had less than this left is
#: reported as ended by a full disk (the ROS logs, also written there, fill the last blocks;
#: the monitor's own error cannot be read when its log could not be written)
NEARLY_FULL = 1 << 20


def no_space_record(prefix, record, missing):
    """If the run did not end normally (or lacks result files) and the file system of
    ``prefix`` is full (less than :data:`NEARLY_FULL` bytes left), the record of a run ended
    by the full disk: status ABORTED, the reason naming the files and the space left. Else
    None. A user's signal stays the run's status."""
    if record.get("signal") or (record["status"] in rs.NORMAL_ENDS and not missing):
        return None
    free = free_bytes(prefix)
    if free is None or free >= NEARLY_FULL:
        return None
    return dict(record, status=rs.ABORTED, culprit=None,
                reason=f"{NoSpaceError(prefix + '_*')}: the result files are incomplete")
