"""Run one full-stack experiment (simulator, navigation, agents, monitor) and supervise it.

Sequence of :meth:`Experiment.run`:

1. claim a unique result prefix ``<results>/<map>_<N>/<ALG>/<host>/<YYYYMMDD_HHMMSS>[_k]``
   and write ``<prefix>_config.yaml`` (the configuration) and ``<prefix>_experiment.launch``;
2. start ``roslaunch -p PORT`` in a new session, with its own master on a free port and
   node logs in ``<prefix>_logs/``;
3. follow ``/stage2d/status`` and ``/results`` (GO, visits, END) and print a progress line
   every few seconds: sim time, complete patrol cycles, average idleness (read from the
   monitor's own files, so the numbers are the monitor's), visits (counted as the monitor
   counts them: reports after GO), pace;
4. supervise every node: roslaunch's own output (``<prefix>_logs/roslaunch.log``) names
   each process that dies (``[robot_0/robot_nav-5] process has died [pid .., exit code ..``,
   ``REQUIRED process [stage2d-2] has died!``, ``cannot launch node of type``); a node that
   dies before the monitor ended the run ends it at once: status ``CRASHED`` naming the node
   (and the robot it serves), its exit code and the last lines of its log;
5. the monitor ends the run itself (timeout in sim seconds since GO, k cycles, dead robot,
   abort) and, being ``required``, takes roslaunch down with it; the runner also stops the
   run on SIGINT / SIGTERM (``INTERRUPTED``), when GO does not come, when sim time stalls or
   when the wall-clock limit is exceeded (``ABORTED``): it sends SIGINT to roslaunch, which
   stops the nodes in order (the monitor writes its files on SIGINT);
6. stops any survivor of its own process tree (never anything else), records the status in
   info.csv's termination field and in ``<prefix>_run.yaml`` (:mod:`patrolling_sim.run_status`)
   and returns an :class:`Outcome`.

Exit codes (:func:`patrolling_sim.run_status.exit_code_for`): 0 normal end (TIMEOUT,
CYCLES, STOPPED), 1 FAIL or ABORTED, 3 CRASHED, 130 SIGINT, 143 SIGTERM.
"""
import glob
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import xmlrpc.client
from dataclasses import dataclass, field

from .. import paths, run_status as rs
from ..errors import PatrolInputError
from ..run_status import NORMAL_ENDS  # noqa: F401 - re-exported (GUI, tests)
from .launchgen import generate_launch, status_topic
from .proctree import ProcessTree
from .rosenv import experiment_env, free_port


def _terminate_with_parent(parent_pid):
    """preexec_fn for roslaunch: the kernel sends it SIGTERM if this runner dies (even by
    SIGKILL), and roslaunch then stops its nodes, so a killed runner leaves no orphans."""
    def setup():
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGTERM), 0, 0, 0)     # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            return
        if os.getppid() != parent_pid:                       # died before prctl took effect
            os.kill(os.getpid(), signal.SIGTERM)
    return setup

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


def hostname():
    try:
        return socket.gethostname() or "default"
    except OSError:
        return "default"


def claim_prefix(cfg, stamp=None):
    """Create the run folder and claim a unique prefix by creating ``<prefix>_config.yaml``
    exclusively (safe against parallel runners). Returns the prefix."""
    folder = os.path.join(os.path.abspath(cfg.results_dir), f"{cfg.result_name}_{cfg.robots}",
                          cfg.alg, hostname())
    os.makedirs(folder, exist_ok=True)
    stamp = stamp or time.strftime("%Y%m%d_%H%M%S")
    for k in range(1000):
        prefix = os.path.join(folder, stamp if k == 0 else f"{stamp}_{k}")
        try:
            fd = os.open(prefix + "_config.yaml", os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            continue
        with os.fdopen(fd, "w") as f:
            f.write(cfg.to_yaml())
        return prefix
    raise PatrolInputError(f"argument --results-dir: cannot create a unique run prefix in {folder}")


def read_progress(prefix):
    """(complete cycles, average idleness or None) from the monitor's files."""
    cycles = 0
    try:
        with open(prefix + "_results.txt", encoding="utf-8") as f:
            for line in f:
                if line.startswith("Complete Patrol Cycles:"):
                    cycles = int(line.split("\t")[-1])
    except (OSError, ValueError):
        pass
    total = n = 0
    try:
        with open(prefix + "_idleness.csv", encoding="utf-8") as f:
            next(f, None)
            for line in f:
                parts = line.split(";")
                if len(parts) >= 4:
                    try:
                        total += float(parts[3])
                        n += 1
                    except ValueError:
                        pass
    except OSError:
        pass
    return cycles, (total / n if n else None)


def read_info(prefix):
    """Fields of ``<prefix>_info.csv`` (list of str) or None."""
    try:
        with open(prefix + "_info.csv", encoding="utf-8") as f:
            line = f.readline().strip()
    except OSError:
        return None
    return line.split(";") if line else None


class _RosWatcher:
    """Follows the experiment from this process: the simulator's status (sim time and
    achieved real-time factor, every 2 s wall; cheaper than /clock at every step) and
    /results (GO, visits)."""

    def __init__(self, master_uri, status="/stage2d/status"):
        os.environ["ROS_MASTER_URI"] = master_uri
        os.environ["ROS_IP"] = "127.0.0.1"
        import rospy
        from std_msgs.msg import Int16MultiArray, String
        self.rospy = rospy
        self.sim_time = 0.0
        self.rtf = None
        self.go = False
        self.sim_at_go = None
        self.end = False
        self.visits = 0
        self._reports = 0
        self._vertices = set()
        self.ready = set()
        rospy.init_node(f"experiment_runner_{os.getpid()}", anonymous=False,
                        disable_signals=True, disable_rosout=False)
        rospy.Subscriber(status, String, self._status, queue_size=1)
        rospy.Subscriber("/results", Int16MultiArray, self._results, queue_size=100)

    def _status(self, msg):
        import json
        try:
            st = json.loads(msg.data)
            self.sim_time = float(st["sim_time"])
            self.rtf = float(st["rtf"])
        except (ValueError, KeyError, TypeError):
            pass

    def _results(self, msg):
        d = list(msg.data)
        if len(d) >= 3 and d[1] == 10:
            if d[0] == -1 and d[2] == 100:
                if not self.go:
                    self.sim_at_go = self.sim_time
                self.go = True
            elif d[0] == -1 and d[2] == 999:
                self.end = True
            elif d[0] >= 0:
                self.ready.add(d[0])
        elif len(d) >= 3 and d[1] == 11 and self.go:
            # counted as the monitor counts them: a vertex's first report (the start
            # vertex, usually) is not a visit (its counter starts at -1)
            self._reports += 1
            self._vertices.add(d[2])
            self.visits = self._reports - len(self._vertices)

    def close(self):
        try:
            self.rospy.signal_shutdown("experiment finished")
        except Exception:   # noqa: BLE001 - best effort at exit
            pass


def _master_up(uri, timeout, stop=lambda: False):
    proxy = xmlrpc.client.ServerProxy(uri)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not stop():
        try:
            code, _, _ = proxy.getSystemState("/experiment_runner")
            if code == 1:
                return True
        except OSError:
            pass
        time.sleep(0.2)
    return False




_ANSI = None


def _strip_ansi(line):
    global _ANSI
    if _ANSI is None:
        import re
        _ANSI = re.compile(r"\x1b\[[0-9;]*m")
    return _ANSI.sub("", line)


def describe_node(node):
    """(description, robot id or None) of a roslaunch process name such as
    ``robot_0/robot_nav-5``, ``stage2d-2``, ``patrol_robot1-9``, ``master``."""
    import re
    name = re.sub(r"-\d+$", "", node.strip("/"))
    m = re.match(r"robot_(\d+)/(.+)$", name)
    if m:
        rid = int(m.group(1))
        return f"robot {rid}'s navigation ({name})", rid
    m = re.match(r"patrol_robot(\d+)$", name)
    if m:
        rid = int(m.group(1))
        return f"robot {rid}'s agent ({name})", rid
    known = {"master": "the ROS master (rosmaster)", "stage2d": "the simulator (stage2d)",
             "monitor": "the monitor", "map_server": "the map server (map_server)",
             "patrol_agents": "the agents (patrol_agents)", "rviz": "rviz"}
    return known.get(name, f"node {name}"), None


class RoslaunchLog:
    """Follows roslaunch's output file and collects the deaths it reports:
    dicts ``{node, exit_code, log, required, launch_error}`` in order."""

    def __init__(self, path):
        self.path = path
        self.pos = 0
        self.partial = ""
        self.deaths = []
        self._pending = None        # REQUIRED process [x] has died! -> next line has the code

    def poll(self):
        try:
            with open(self.path, encoding="utf-8", errors="replace") as f:
                f.seek(self.pos)
                data = f.read()
                self.pos = f.tell()
        except OSError:
            return []
        if not data:
            return []
        text = self.partial + data
        lines = text.split("\n")
        self.partial = lines.pop()
        new = []
        for line in lines:
            d = self._line(_strip_ansi(line).strip())
            if d is not None:
                self.deaths.append(d)
                new.append(d)
        return new

    def _line(self, line):
        import re
        m = re.search(r"REQUIRED process \[([^\]]+)\] has died!", line)
        if m:
            self._pending = {"node": m.group(1), "exit_code": None, "log": None,
                             "required": True, "launch_error": False}
            return None
        if self._pending is not None:
            d = self._pending
            m = re.search(r"exit code (-?\d+)", line)
            if m:
                d["exit_code"] = int(m.group(1))
                return None
            if "finished cleanly" in line:
                d["exit_code"] = 0
                return None
            if line.startswith("log file:"):
                d["log"] = line[len("log file:"):].strip()
                return None
            if "without exit code" in line:
                return None
            self._pending = None
            return d
        m = re.match(r"\[([^\]]+)\] process has (died|finished cleanly)(.*)$", line)
        if m:
            code = re.search(r"exit code (-?\d+)", m.group(3))
            d = {"node": m.group(1), "exit_code": int(code.group(1)) if code else
                 (0 if m.group(2) == "finished cleanly" else None), "log": None,
                 "required": False, "launch_error": False}
            self._last = d
            return d
        if line.startswith("log file:") and self.deaths:
            self.deaths[-1]["log"] = line[len("log file:"):].strip()
            return None
        m = re.search(r"cannot launch node of type \[([^\]]+)\]", line)
        if m:
            return {"node": m.group(1), "exit_code": None, "log": None, "required": False,
                    "launch_error": True, "message": line}
        return None


def _signal_name(reason):
    return reason if reason in ("SIGINT", "SIGTERM") else None


class Experiment:
    """One experiment run. ``out`` receives the progress/status lines."""

    GO_TIMEOUT = 180.0          # wall s from launch to GO
    STALL_TIMEOUT = 90.0        # wall s without /clock progress after GO
    CLEAN_EXIT_GRACE = 2.0      # wall s to wait for END after a node exited with code 0

    def __init__(self, cfg, out=None, progress_period=5.0):
        self.cfg = cfg
        self.out = out or (lambda s: print(s, flush=True))
        self.progress_period = progress_period
        self._stop_reason = None
        self._lock = threading.Lock()
        self.prefix = None

    def request_stop(self, reason):
        """Ask the run to stop (thread/signal safe). ``reason``: "SIGINT", "SIGTERM" or a
        sentence."""
        with self._lock:
            if self._stop_reason is None:
                self._stop_reason = reason

    def _stop_requested(self):
        with self._lock:
            return self._stop_reason

    def wall_limit(self):
        cfg = self.cfg
        if cfg.timeout > 0 and cfg.speedup > 0:
            return cfg.timeout / cfg.speedup * 4 + 300
        return None

    def prepare(self):
        cfg = self.cfg
        positions = cfg.start_positions()
        self.prefix = claim_prefix(cfg)
        from ..startpos import write_start_poses
        write_start_poses(self.prefix + "_start_poses.txt", positions, cfg.map,
                          f"--initpos {cfg.initpos}")
        self.log_dir = self.prefix + "_logs"
        os.makedirs(self.log_dir, exist_ok=True)
        snap = None
        if cfg.record:
            snap = self.prefix + "_snapshots"
            os.makedirs(snap, exist_ok=True)
        self.snapshot_dir = snap
        rviz_config = None
        if cfg.rviz:
            # an rviz view of exactly this team, centred on this map, kept with the results
            from ..report.rviz_config import experiment_config_text
            rviz_config = self.prefix + "_patrol.rviz"
            with open(rviz_config, "w", encoding="utf-8") as f:
                f.write(experiment_config_text(cfg.robots, cfg.map))
        self.launch_path = self.prefix + "_experiment.launch"
        with open(self.launch_path, "w", encoding="utf-8") as f:
            f.write(generate_launch(cfg, positions, self.prefix, snapshot_dir=snap,
                                    rviz_config=rviz_config))
        return self.prefix

    def run(self):
        """Run and supervise; always returns an Outcome (the status is recorded in the
        files). A stop request (signal) at any moment ends the run within seconds."""
        cfg = self.cfg
        t_start = time.monotonic()
        self.prepare()
        if self._stop_requested():
            return self._finalise(t_start, None, None, None, None)
        port = free_port()
        env = experiment_env(port, self.log_dir)
        uri = env["ROS_MASTER_URI"]
        self.out(f"experiment: {cfg.map_name}, {cfg.robots} robots, {cfg.alg}, {cfg.loc}, "
                 f"{cfg.nav}; master {uri}; results {self.prefix}_*")
        log_path = os.path.join(self.log_dir, "roslaunch.log")
        log = open(log_path, "w")
        proc = subprocess.Popen(["roslaunch", "-p", str(port), "--skip-log-check",
                                 self.launch_path], env=env, stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True,
                                cwd=self.log_dir, preexec_fn=_terminate_with_parent(os.getpid()))
        tree = ProcessTree(proc.pid)
        rl = RoslaunchLog(log_path)
        watcher = None
        abort_reason = None      # the runner's own reason to end the run (ABORTED)
        crash = None             # the first node death that ends the run (CRASHED)
        go_wall = None
        clean_exit_at = None
        try:
            if not _master_up(uri, 30, self._stop_requested):
                if not self._stop_requested():
                    abort_reason = "the ROS master did not come up within 30 s"
            elif not self._stop_requested():
                watcher = _RosWatcher(uri, status_topic(cfg))
            last_print = 0.0
            last_clock = (0.0, time.monotonic())
            limit = self.wall_limit()
            last_refresh = 0.0
            while abort_reason is None and crash is None:
                now = time.monotonic()
                if now - last_refresh >= 2.0:   # remember our descendants (reads all of /proc)
                    tree.refresh()
                    last_refresh = now
                if self._stop_requested():
                    break
                ended = watcher is not None and watcher.end
                for d in rl.poll():
                    desc, _ = describe_node(d["node"])
                    if d["launch_error"]:
                        crash = d
                    elif desc == "the monitor" and d["exit_code"] == 0:
                        pass                    # the monitor ended the run itself
                    elif ended:
                        pass                    # the run is over: nodes exit after END
                    elif d["exit_code"] == 0 and not d["required"]:
                        clean_exit_at = clean_exit_at or (now, d)
                    else:
                        crash = d
                    if crash:
                        break
                if crash is not None:
                    break
                if clean_exit_at is not None and not ended and \
                        now - clean_exit_at[0] > self.CLEAN_EXIT_GRACE:
                    crash = clean_exit_at[1]     # exited cleanly, but before the run's end
                    break
                if proc.poll() is not None:
                    rl.poll()
                    break
                if watcher is not None:
                    if watcher.go and go_wall is None:
                        go_wall = now - t_start
                        self.out(f"GO after {go_wall:.1f} s (wall)")
                    if not watcher.go and now - t_start > self.GO_TIMEOUT:
                        abort_reason = (f"no GO from the monitor within {self.GO_TIMEOUT:.0f} s "
                                        f"({len(watcher.ready)}/{cfg.robots} robots ready)")
                        break
                    if watcher.sim_time > last_clock[0]:
                        last_clock = (watcher.sim_time, now)
                    elif watcher.go and now - last_clock[1] > self.STALL_TIMEOUT:
                        abort_reason = f"simulated time stalled for {self.STALL_TIMEOUT:.0f} s"
                        break
                    if now - last_print >= self.progress_period:
                        last_print = now
                        cycles, avg = read_progress(self.prefix)
                        avg_s = f"{avg:.1f} s" if avg is not None else "-"
                        rtf_s = f"{watcher.rtf:.2f}x" if watcher.rtf else "-"
                        self.out(f"progress: sim {watcher.sim_time:.1f} s | go "
                                 f"{'yes' if watcher.go else 'no'} | cycles {cycles} | "
                                 f"avg idleness {avg_s} | visits {watcher.visits} | "
                                 f"pace {rtf_s}")
                if limit and now - t_start > limit:
                    abort_reason = f"wall-clock limit of {limit:.0f} s exceeded"
                    break
                time.sleep(0.25)
        except KeyboardInterrupt:
            self.request_stop("SIGINT")
        finally:
            self._shutdown(proc, tree)
            if watcher is not None:
                watcher.close()
            log.close()
        if crash is None and not self._stop_requested():
            for d in rl.poll() + rl.deaths:     # a death roslaunch reported as it ended
                desc, _ = describe_node(d["node"])
                if d["launch_error"] or (desc != "the monitor" and d["exit_code"] not in (0, None)
                                         and not (watcher and watcher.end)):
                    crash = d
                    break
                if desc == "the monitor" and d["exit_code"] not in (0, None):
                    crash = d
                    break
        return self._finalise(t_start, watcher, go_wall, abort_reason, crash)

    def _shutdown(self, proc, tree):
        """Orderly shutdown: SIGINT to roslaunch, which stops the nodes (the monitor writes
        its files); a second signal from the user makes it hard; then make sure nothing of
        ours survives."""
        tree.refresh()
        if proc.poll() is None:
            try:
                os.kill(proc.pid, signal.SIGINT)
            except OSError:
                pass
            first = self._stop_requested()
            # a user's signal: stop within 10 s (the monitor writes its files on the first
            # SIGINT at once); otherwise give roslaunch time for an orderly shutdown
            deadline = time.monotonic() + (6 if _signal_name(first) else 20)
            while proc.poll() is None and time.monotonic() < deadline:
                try:
                    time.sleep(0.2)
                    tree.refresh()
                except KeyboardInterrupt:
                    self.request_stop("SIGINT")
                    break
                if first is None and self._stop_requested():
                    first = self._stop_requested()
                    deadline = min(deadline, time.monotonic() + 6)  # stop within 10 s
        hard = tree.stop(grace=1.0 if _signal_name(self._stop_requested()) else 3.0)
        if hard:
            self.out(f"warning: killed {len(hard)} process(es) that ignored SIGINT/SIGTERM")
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            pass

    def _finalise(self, t_start, watcher, go_wall, abort_reason, crash):
        """Decide the status, record it in info.csv and <prefix>_run.yaml, build the Outcome."""
        cfg = self.cfg
        wall = time.monotonic() - t_start
        files = [self.prefix + "_" + s for s in RESULT_SUFFIXES]
        info = read_info(self.prefix)
        mon = rs.read_run_yaml(self.prefix) or {}
        stop = self._stop_requested()
        sig = _signal_name(stop)
        record = {"status": None, "reason": "", "culprit": None, "robots": [], "signal": None}
        monitor_status = rs.normalise(info[13]) if info and len(info) > 13 else None
        if monitor_status == rs.INTERRUPTED:
            monitor_status = None       # the monitor was stopped from outside: not its verdict
        if sig:
            record.update(status=rs.INTERRUPTED, signal=sig,
                          reason=f"interrupted by {sig}")
        elif stop:
            record.update(status=rs.ABORTED, reason=stop)
        elif crash is not None:
            desc, rid = describe_node(crash["node"])
            code = crash["exit_code"]
            if crash["launch_error"]:
                why = f"roslaunch could not start {desc} ({crash.get('message', '')})"
            else:
                why = (f"{desc} died (exit {code})" if code not in (0, None) else
                       f"{desc} exited before the end of the run" if code == 0 else
                       f"{desc} died")
            record.update(status=rs.CRASHED, reason=why, culprit={
                "node": crash["node"], "description": desc, "robot": rid, "exit_code": code,
                "log": crash["log"], "log_tail": rs.log_tail(crash["log"]) if crash["log"]
                else []})
        elif abort_reason:
            record.update(status=rs.ABORTED, reason=abort_reason)
        elif info is None:
            record.update(status=rs.CRASHED, reason="the monitor ended without writing "
                          "info.csv (see the logs)", culprit={"node": "monitor",
                                                              "description": "the monitor",
                                                              "robot": None, "exit_code": None,
                                                              "log": None, "log_tail": []})
        elif monitor_status:
            record.update(status=monitor_status, reason=mon.get("reason") or
                          f"ended: {monitor_status}", robots=mon.get("robots") or [])
        else:
            record.update(status=rs.CRASHED, reason="roslaunch ended the run without a node "
                          "reporting its death (see roslaunch.log)",
                          culprit={"node": "roslaunch", "description": "roslaunch",
                                   "robot": None, "exit_code": None, "log": None,
                                   "log_tail": []})
        status = record["status"]
        code = rs.exit_code_for(status, sig)
        missing = [os.path.basename(f) for f in files if not os.path.isfile(f)]
        if missing and code == rs.EXIT_OK:
            status, code = rs.ABORTED, rs.EXIT_FAILED
            record.update(status=status, reason=f"missing result files: {', '.join(missing)}")
        if info is not None:
            rs.set_info_status(self.prefix, status)
        sim = None
        if info is not None and len(info) > 10:
            try:
                sim = float(info[10])
            except ValueError:
                sim = None
        if sim is None and watcher is not None and watcher.sim_at_go is not None:
            sim = max(0.0, watcher.sim_time - watcher.sim_at_go)
        real = None         # wall seconds since GO: the monitor's own figure if it wrote one
        if info is not None and len(info) > 11:
            try:
                real = float(info[11])
            except ValueError:
                real = None
        if not real and go_wall is not None:
            real = wall - go_wall
        pace = sim / real if sim and real and real > 0 else None
        record.update(
            sim_time=round(sim, 1) if sim is not None else 0.0,
            wall_time=round(wall, 1), go_after=round(go_wall, 1) if go_wall is not None
            else None, pace=round(pace, 2) if pace else None, exit_code=code,
            files_complete=not missing and info is not None, missing_files=missing,
            requested={"timeout": cfg.timeout, "cycles": cfg.cycles,
                       "dead_robot_timeout": cfg.dead_robot_timeout},
            written_by="runner")
        try:
            rs.write_run_yaml(self.prefix, record)
        except OSError as e:
            self.out(f"warning: cannot write {self.prefix}_run.yaml ({e.strerror})")
        why = f"{status}: {record['reason']}" if record["reason"] and \
            record["reason"] != f"ended: {status}" else status
        if status == rs.FAIL and record["robots"]:
            why = f"FAIL: robot(s) {', '.join(map(str, record['robots']))} sent no visit for " \
                  f"{cfg.dead_robot_timeout:g} sim s"
        return Outcome(code, why, self.prefix, [f for f in files if os.path.isfile(f)],
                       sim or 0.0, wall, go_wall, status, record)
