"""Run one full-stack experiment (simulator, navigation, agents, monitor) and supervise it.

Sequence of :meth:`Experiment.run`:

1. claim a unique result prefix ``<results>/<map>_<N>/<ALG>/<host>/<YYYYMMDD_HHMMSS>[_k]``
   and write ``<prefix>_config.yaml`` (the configuration) and ``<prefix>_experiment.launch``;
2. start ``roslaunch -p PORT`` in a new session, with its own master on a free port and
   node logs in ``<prefix>_logs/``;
3. follow ``/clock`` and ``/results`` (GO, visits) and print a progress line every few
   seconds: sim time, complete patrol cycles, average idleness (read from the monitor's
   own files, so the numbers are the monitor's);
4. the monitor ends the run itself (timeout in sim seconds since GO, k cycles, dead robot,
   abort) and, being ``required``, takes roslaunch down with it; the runner also stops the
   run on Ctrl-C / SIGTERM, when GO does not come, when sim time stalls or when the
   wall-clock limit is exceeded: it sends SIGINT to roslaunch, which stops the nodes in
   order (the monitor writes info.csv on SIGINT);
5. stops any survivor of its own process tree (never anything else), checks the four
   result files and returns an :class:`Outcome`.

Exit codes: 0 run ended normally (TIMEOUT or CYCLES), 1 the run failed (FAIL, ABORT, a
crashed monitor, missing files, no GO, stall), 130 interrupted by the user.
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

from .. import paths
from ..errors import PatrolInputError
from .launchgen import generate_launch
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
#: terminations that count as a successful run (STOPPED: /simulation_running set false,
#: e.g. by the GUI's Stop button)
NORMAL_ENDS = ("TIMEOUT", "CYCLES", "STOPPED")


@dataclass
class Outcome:
    exit_code: int
    reason: str
    prefix: str = ""
    files: list = field(default_factory=list)
    sim_time: float = 0.0
    wall_time: float = 0.0
    go_wall: float = None      # wall seconds from launch to GO


def hostname():
    try:
        return socket.gethostname() or "default"
    except OSError:
        return "default"


def claim_prefix(cfg, stamp=None):
    """Create the run folder and claim a unique prefix by creating ``<prefix>_config.yaml``
    exclusively (safe against parallel runners). Returns the prefix."""
    folder = os.path.join(os.path.abspath(cfg.results_dir), f"{cfg.map_name}_{cfg.robots}",
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

    def __init__(self, master_uri):
        os.environ["ROS_MASTER_URI"] = master_uri
        os.environ["ROS_IP"] = "127.0.0.1"
        import rospy
        from std_msgs.msg import Int16MultiArray, String
        self.rospy = rospy
        self.sim_time = 0.0
        self.rtf = None
        self.go = False
        self.visits = 0
        self.ready = set()
        rospy.init_node(f"experiment_runner_{os.getpid()}", anonymous=False,
                        disable_signals=True, disable_rosout=False)
        rospy.Subscriber("/stage2d/status", String, self._status, queue_size=1)
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
                self.go = True
            elif d[0] >= 0:
                self.ready.add(d[0])
        elif len(d) >= 3 and d[1] == 11 and self.go:
            self.visits += 1

    def close(self):
        try:
            self.rospy.signal_shutdown("experiment finished")
        except Exception:   # noqa: BLE001 - best effort at exit
            pass


def _master_up(uri, timeout):
    proxy = xmlrpc.client.ServerProxy(uri)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            code, _, _ = proxy.getSystemState("/experiment_runner")
            if code == 1:
                return True
        except OSError:
            pass
        time.sleep(0.2)
    return False


class Experiment:
    """One experiment run. ``out`` receives the progress/status lines."""

    GO_TIMEOUT = 180.0          # wall s from launch to GO
    STALL_TIMEOUT = 90.0        # wall s without /clock progress after GO

    def __init__(self, cfg, out=None, progress_period=5.0):
        self.cfg = cfg
        self.out = out or (lambda s: print(s, flush=True))
        self.progress_period = progress_period
        self._stop_reason = None
        self._lock = threading.Lock()

    def request_stop(self, reason):
        """Ask the run to stop (thread/signal safe)."""
        with self._lock:
            if self._stop_reason is None:
                self._stop_reason = reason

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
        cfg = self.cfg
        t_start = time.monotonic()
        self.prepare()
        port = free_port()
        env = experiment_env(port, self.log_dir)
        uri = env["ROS_MASTER_URI"]
        self.out(f"experiment: {cfg.map_name}, {cfg.robots} robots, {cfg.alg}, {cfg.loc}, "
                 f"{cfg.nav}; master {uri}; results {self.prefix}_*")
        log = open(os.path.join(self.log_dir, "roslaunch.log"), "w")
        proc = subprocess.Popen(["roslaunch", "-p", str(port), "--skip-log-check",
                                 self.launch_path], env=env, stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True,
                                cwd=self.log_dir, preexec_fn=_terminate_with_parent(os.getpid()))
        tree = ProcessTree(proc.pid)
        watcher = None
        outcome_reason = None
        go_wall = None
        interrupted = False
        try:
            if not _master_up(uri, 30):
                outcome_reason = "the ROS master did not come up within 30 s"
            else:
                watcher = _RosWatcher(uri)
            last_print = 0.0
            last_clock = (0.0, time.monotonic())
            limit = self.wall_limit()
            last_refresh = 0.0
            while outcome_reason is None:
                now = time.monotonic()
                if now - last_refresh >= 2.0:   # remember our descendants (reads all of /proc)
                    tree.refresh()
                    last_refresh = now
                if proc.poll() is not None:
                    break
                with self._lock:
                    reason = self._stop_reason
                if reason:
                    interrupted = reason == "interrupted"
                    outcome_reason = reason
                    break
                if watcher is not None:
                    if watcher.go and go_wall is None:
                        go_wall = now - t_start
                        self.out(f"GO after {go_wall:.1f} s (wall)")
                    if not watcher.go and now - t_start > self.GO_TIMEOUT:
                        outcome_reason = (f"no GO from the monitor within {self.GO_TIMEOUT:.0f} s "
                                          f"({len(watcher.ready)}/{cfg.robots} robots ready)")
                        break
                    if watcher.sim_time > last_clock[0]:
                        last_clock = (watcher.sim_time, now)
                    elif watcher.go and now - last_clock[1] > self.STALL_TIMEOUT:
                        outcome_reason = f"simulated time stalled for {self.STALL_TIMEOUT:.0f} s"
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
                    outcome_reason = f"wall-clock limit of {limit:.0f} s exceeded"
                    break
                time.sleep(0.25)
        except KeyboardInterrupt:
            interrupted = True
            outcome_reason = "interrupted"
        finally:
            # orderly shutdown: SIGINT to roslaunch, which stops the nodes (monitor writes
            # its files); then make sure nothing of ours survives
            tree.refresh()
            if proc.poll() is None:
                try:
                    os.kill(proc.pid, signal.SIGINT)
                except OSError:
                    pass
                deadline = time.monotonic() + 40
                while proc.poll() is None and time.monotonic() < deadline:
                    try:
                        time.sleep(0.2)
                        tree.refresh()
                    except KeyboardInterrupt:
                        interrupted = True
            if watcher is not None:
                watcher.close()
            hard = tree.stop(grace=5.0)
            if hard:
                self.out(f"warning: killed {len(hard)} process(es) that ignored SIGINT/SIGTERM")
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass
            log.close()
        wall = time.monotonic() - t_start
        return self._outcome(outcome_reason, interrupted, watcher, go_wall, wall)

    def _outcome(self, reason, interrupted, watcher, go_wall, wall):
        files = [self.prefix + "_" + s for s in RESULT_SUFFIXES]
        missing = [f for f in files if not os.path.isfile(f)]
        info = read_info(self.prefix)
        sim = watcher.sim_time if watcher else 0.0
        if interrupted:
            code, why = 130, "interrupted by the user"
        elif reason:
            code, why = 1, reason
        elif info is None:
            code, why = 1, "the monitor ended without writing info.csv (see the logs)"
        elif len(info) > 13 and info[13] in NORMAL_ENDS:
            code, why = 0, f"ended: {info[13]}"
        else:
            code, why = 1, f"ended: {info[13] if info and len(info) > 13 else 'unknown'}"
        if missing and code == 0:
            code, why = 1, f"missing result files: {', '.join(os.path.basename(m) for m in missing)}"
        return Outcome(code, why, self.prefix, [f for f in files if os.path.isfile(f)], sim, wall,
                       go_wall)
