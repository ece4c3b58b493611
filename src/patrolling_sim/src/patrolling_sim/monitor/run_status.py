"""How a run ended: the status words, the exit codes and ``<prefix>_run.yaml``.

Every run (ROS runner, monitor alone, graph mode) records its end in two places:

- field 14 of ``<prefix>_info.csv`` (the original's ``termination`` field): one status word;
- ``<prefix>_run.yaml``, machine-readable, next to the four result files::

      status: CRASHED            # one of STATUSES
      reason: "the simulator (stage2d) died (exit -9)"
      culprit: {node: stage2d, exit_code: -9, robot: null, log_tail: [...]}
      robots: []                 # FAIL: the silent robots' ids
      longest_silence: [41.2, 230.4]   # per robot id: longest sim s without a visit report
      signal: null               # INTERRUPTED: SIGINT / SIGTERM
      sim_time: 63.2             # sim seconds since GO reached
      wall_time: 41.0            # wall seconds of the whole run
      pace: 1.54                 # sim_time / wall seconds since GO
      exit_code: 3               # the runner's exit code (null: the runner did not finish)
      complete: false            # true only for a normal end (TIMEOUT / CYCLES / STOPPED)
      written_by: runner         # runner | monitor | graph_sim

Statuses (docs/monitor.md explains each):

=============  =========================================================  =====
status         meaning                                                    exit
=============  =========================================================  =====
TIMEOUT        the timeout in sim seconds since GO was reached            0
CYCLES         the requested number of complete patrol cycles was done    0
STOPPED        ``/simulation_running`` set false (the GUI's Stop button)  0
FAIL           a robot sent no visit for ``dead_robot_timeout`` sim s     1
ABORTED        ended early for another reason: ``/simulation_abort``,     1
               no GO, simulated time stalled, wall-clock limit
CRASHED        a node the experiment needs died                           3
INTERRUPTED    SIGINT (exit 130) or SIGTERM (exit 143), or the run was    130/143
               stopped from outside the monitor
=============  =========================================================  =====

The original writes ``ABORT`` for an aborted run; it is read as ``ABORTED``.
"""
import yaml
import glob

from patrolling_sim.common.textfile import write_atomic

TIMEOUT, CYCLES, STOPPED, FAIL = "TIMEOUT", "CYCLES", "STOPPED", "FAIL"
ABORTED, CRASHED, INTERRUPTED = "ABORTED", "CRASHED", "INTERRUPTED"
STATUSES = (TIMEOUT, CYCLES, STOPPED, FAIL, ABORTED, CRASHED, INTERRUPTED)
#: a complete run: its metrics cover the whole requested experiment
NORMAL_ENDS = (TIMEOUT, CYCLES, STOPPED)
#: words written by the original (and older versions of this project) -> status
ALIASES = {"ABORT": ABORTED}

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_CRASHED = 0, 1, 2, 3
EXIT_SIGINT, EXIT_SIGTERM = 130, 143
SIGNAL_EXIT = {"SIGINT": EXIT_SIGINT, "SIGTERM": EXIT_SIGTERM}


def normalise(word):
    """Status word of an info.csv field (unknown words are returned unchanged)."""
    w = str(word or "").strip().upper()
    return ALIASES.get(w, w)


def exit_code_for(status, signal_name=None):
    if status in NORMAL_ENDS:
        return EXIT_OK
    if status == INTERRUPTED:
        return SIGNAL_EXIT.get(signal_name, EXIT_SIGINT)
    if status == CRASHED:
        return EXIT_CRASHED
    return EXIT_FAILED


def run_yaml_path(prefix):
    return prefix + "_run.yaml"


def write_run_yaml(prefix, record):
    """Write ``<prefix>_run.yaml`` atomically (temporary file + rename)."""
    rec = dict(record)
    rec["complete"] = rec.get("status") in NORMAL_ENDS
    text = yaml.safe_dump(rec, sort_keys=False, default_flow_style=False, allow_unicode=True)
    return write_atomic(run_yaml_path(prefix), text)


def read_run_yaml(prefix):
    """The record of ``<prefix>_run.yaml`` (dict) or None if absent or unreadable."""
    try:
        with open(run_yaml_path(prefix), encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except (OSError, yaml.YAMLError):
        return None
    return data if isinstance(data, dict) else None


def set_info_status(prefix, status):
    """Rewrite field 14 (termination) of ``<prefix>_info.csv`` to ``status`` atomically.
    Returns False if there is no well-formed info.csv."""
    return set_info_field(prefix, 13, status)


def set_info_field(prefix, index, value):
    """Rewrite field ``index`` (0-based) of ``<prefix>_info.csv`` atomically. Returns False
    if there is no well-formed info.csv."""
    path = prefix + "_info.csv"
    try:
        with open(path, encoding="utf-8") as f:
            line = f.readline().rstrip("\n")
    except OSError:
        return False
    fields = line.split(";")
    if len(fields) != 22:
        return False
    fields[index] = str(value).replace(";", ",")
    write_atomic(path, ";".join(fields) + "\n")
    return True


def log_tail(path_pattern, lines=10):
    """Last ``lines`` lines of the node log(s) roslaunch names as ``<path>*.log``."""
    out = []
    base = path_pattern[:-len("*.log")] if path_pattern.endswith("*.log") else path_pattern
    for p in sorted(glob.glob(base + "*.log")):
        try:
            with open(p, encoding="utf-8", errors="replace") as f:
                tail = [ln.rstrip("\n") for ln in f.readlines()[-lines:]]
        except OSError:
            continue
        out += [ln for ln in tail if ln.strip()]
    return out[-lines:]


def silence_warning(silences, dead_robot_timeout):
    """A line naming the robots that sent no visit report for more than half the dead-robot
    time (``silences``: each robot's longest silence, ``_run.yaml``'s ``longest_silence``)
    without reaching it, or None: such a run may still end normally (TIMEOUT), with a robot
    that stood still for minutes; 0 (no dead-robot rule) gives no warning."""
    if not dead_robot_timeout or dead_robot_timeout <= 0:
        return None
    long = [(r, s) for r, s in enumerate(silences or [])
            if dead_robot_timeout / 2 < s <= dead_robot_timeout]
    if not long:
        return None
    who = ", ".join(f"robot {r} {s:.0f} s" for r, s in long)
    return (f"longest time without a visit report: {who} (more than half the dead-robot "
            f"time of {dead_robot_timeout:g} sim s; see longest_silence in _run.yaml)")


def silences_of(record):
    """``longest_silence`` of a ``_run.yaml`` record (dict or None) as floats, one per robot
    id; [] if the record has none (older runs) or it is malformed."""
    try:
        return [float(x) for x in (record or {}).get("longest_silence") or []]
    except (TypeError, ValueError, AttributeError):
        return []


def longest_silence(silences):
    """(seconds, robot id) of the longest of ``silences`` (:func:`silences_of`), the lowest id
    of equal ones; (None, None) for an empty list."""
    if not silences:
        return None, None
    r = max(range(len(silences)), key=silences.__getitem__)
    return silences[r], r
