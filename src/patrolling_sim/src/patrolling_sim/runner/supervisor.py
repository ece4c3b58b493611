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
   info.csv's termination field and in ``<prefix>_run.yaml``
   (:mod:`patrolling_sim.monitor.run_status`) and returns an :class:`Outcome`.

Exit codes (:func:`patrolling_sim.monitor.run_status.exit_code_for`): 0 normal end (TIMEOUT,
CYCLES, STOPPED), 1 FAIL or ABORTED, 3 CRASHED, 130 SIGINT, 143 SIGTERM.
"""
import os
import signal
import subprocess
import threading
import time
from dataclasses import dataclass

from patrolling_sim.monitor import run_status as rs
from patrolling_sim.monitor.results import claim_prefix as _claim, default_prefix
from patrolling_sim.runner.launchgen import generate_launch, status_topic
from patrolling_sim.runner.outcome import (RESULT_SUFFIXES, Outcome, clock_record, decide_status,
                                           late_crash, missing_files, no_space_record, read_info,
                                           signal_name, summary, timing)
from patrolling_sim.runner.proctree import ProcessTree
from patrolling_sim.runner.roslaunch_log import RoslaunchLog, is_monitor
from patrolling_sim.runner.rosenv import experiment_env, free_port
from patrolling_sim.runner.watch import RosWatcher, master_up, progress_line
from patrolling_sim.report.rviz_config import experiment_config_text
from patrolling_sim.startpos.explicit import initpos_label
from patrolling_sim.startpos.optimised import write_start_poses
import ctypes


def _terminate_with_parent(parent_pid):
    """preexec_fn for roslaunch: the kernel sends it SIGTERM if this runner dies (even by
    SIGKILL), and roslaunch then stops its nodes, so a killed runner leaves no orphans."""
    def setup():
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGTERM), 0, 0, 0)     # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            return
        if os.getppid() != parent_pid:                       # died before prctl took effect
            os.kill(os.getpid(), signal.SIGTERM)
    return setup


def claim_prefix(cfg, stamp=None, start_vertices=None):
    """Create the run folder and claim a unique prefix
    ``<results>/<map>_<N>/<ALG>/<host>/<stamp>[_k]`` by creating ``<prefix>_config.yaml``
    exclusively (safe against parallel runners) with the configuration in it, and the
    resolved ``start_vertices`` (one per robot) when given."""
    return _claim(default_prefix(os.path.abspath(cfg.results_dir), cfg.result_name,
                                 cfg.robots, cfg.alg, stamp=stamp),
                  "_config.yaml", cfg.to_yaml(start_vertices))


@dataclass
class _Run:
    """What the supervisor knows about the run in progress."""
    t_start: float
    proc: subprocess.Popen = None
    tree: ProcessTree = None
    log: RoslaunchLog = None
    watcher: RosWatcher = None
    abort_reason: str = None     # the runner's own reason to end the run (ABORTED)
    crash: dict = None           # the first node death that ends the run (CRASHED)
    go_wall: float = None        # wall s from launch to GO
    clean_exit_at: tuple = None  # (wall time, death) of a node that exited with code 0
    last_print: float = 0.0
    last_clock: tuple = None     # (sim time, wall time) of the last sim-time progress
    last_refresh: float = 0.0

    @property
    def ended(self):
        """The monitor announced the run's END."""
        return self.watcher is not None and self.watcher.end


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
        if cfg.timeout > 0:     # --speedup auto: at least real time
            return cfg.timeout / (cfg.speedup or 1.0) * 4 + 300
        return None

    def prepare(self):
        cfg = self.cfg
        positions, pgraph = cfg.start_poses()
        # a robot's start vertex is the vertex nearest its pose, as its agent finds it
        self.prefix = claim_prefix(cfg, start_vertices=[pgraph.nearest_vertex(x, y)
                                                        for x, y in positions])
        write_start_poses(self.prefix + "_start_poses.txt", positions, pgraph,
                          initpos_label(cfg.initpos, cfg.seed))
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
        run = _Run(t_start=time.monotonic())
        self.prepare()
        if self._stop_requested():
            return self._finalise(run)
        log_file = self._start_roslaunch(run)
        try:
            self._connect(run)
            if run.abort_reason is None:
                self._supervise(run)
        except KeyboardInterrupt:
            self.request_stop("SIGINT")
        finally:
            self._shutdown(run.proc, run.tree, before_go=run.go_wall is None)
            if run.watcher is not None:
                run.watcher.close()
            log_file.close()
        if run.crash is None and not self._stop_requested():
            # a death roslaunch reported as it ended
            run.crash = late_crash(run.log.poll() + run.log.deaths, run.ended)
        return self._finalise(run)

    # -- the steps of run() -------------------------------------------------------------

    def _start_roslaunch(self, run):
        """Start ``roslaunch -p PORT`` (own master on a free port) in a new session, its
        output in ``<prefix>_logs/roslaunch.log``; returns that open log file."""
        cfg = self.cfg
        port = free_port()
        env = experiment_env(port, self.log_dir)
        self.master_uri = env["ROS_MASTER_URI"]
        self.out(f"experiment: {cfg.map_name}, {cfg.robots} robots, {cfg.alg}, {cfg.loc}, "
                 f"{cfg.nav}; master {self.master_uri}; results {self.prefix}_*")
        log_path = os.path.join(self.log_dir, "roslaunch.log")
        log_file = open(log_path, "w")
        run.proc = subprocess.Popen(
            ["roslaunch", "-p", str(port), "--skip-log-check", self.launch_path], env=env,
            stdout=log_file, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            start_new_session=True, cwd=self.log_dir,
            preexec_fn=_terminate_with_parent(os.getpid()))
        run.tree = ProcessTree(run.proc.pid)
        run.log = RoslaunchLog(log_path)
        return log_file

    def _connect(self, run):
        """Wait for the master, then follow the run's topics."""
        if not master_up(self.master_uri, 30, self._stop_requested):
            if not self._stop_requested():
                run.abort_reason = "the ROS master did not come up within 30 s"
        elif not self._stop_requested():
            run.watcher = RosWatcher(self.master_uri, status_topic(self.cfg))
        run.last_clock = (0.0, time.monotonic())

    def _supervise(self, run):
        """Poll four times a second until something ends the run: a stop request, a node's
        death, roslaunch's end, or one of the runner's own limits."""
        limit = self.wall_limit()
        while True:
            now = time.monotonic()
            if now - run.last_refresh >= 2.0:   # remember our descendants (reads all of /proc)
                run.tree.refresh()
                run.last_refresh = now
            if self._stop_requested() or self._node_deaths(run, now):
                return
            if run.proc.poll() is not None:
                run.log.poll()
                return
            if run.watcher is not None and self._follow_progress(run, now):
                return
            if limit and now - run.t_start > limit:
                run.abort_reason = f"wall-clock limit of {limit:.0f} s exceeded"
                return
            time.sleep(0.25)

    def _node_deaths(self, run, now):
        """Read roslaunch's new death reports; True (``run.crash`` set) if one ends the run.
        The monitor's clean exit and exits after END are the run's normal end; a clean exit
        of another node before END is a crash once CLEAN_EXIT_GRACE has passed."""
        ended = run.ended
        for d in run.log.poll():
            if d["launch_error"]:
                run.crash = d
            elif is_monitor(d) and d["exit_code"] == 0:
                pass                    # the monitor ended the run itself
            elif ended:
                pass                    # the run is over: nodes exit after END
            elif d["exit_code"] == 0 and not d["required"]:
                run.clean_exit_at = run.clean_exit_at or (now, d)
            else:
                run.crash = d
            if run.crash:
                return True
        if run.clean_exit_at is not None and not ended and \
                now - run.clean_exit_at[0] > self.CLEAN_EXIT_GRACE:
            run.crash = run.clean_exit_at[1]     # exited cleanly, but before the run's end
            return True
        return False

    def _follow_progress(self, run, now):
        """GO, sim-time progress and the progress line; True (``run.abort_reason`` set) if
        GO does not come or sim time stalls."""
        w = run.watcher
        if w.go and run.go_wall is None:
            run.go_wall = now - run.t_start
            self.out(f"GO after {run.go_wall:.1f} s (wall)")
        if not w.go and now - run.t_start > self.GO_TIMEOUT:
            run.abort_reason = (f"no GO from the monitor within {self.GO_TIMEOUT:.0f} s "
                                f"({len(w.ready)}/{self.cfg.robots} robots ready)")
            return True
        if w.sim_time > run.last_clock[0]:
            run.last_clock = (w.sim_time, now)
        elif w.go and now - run.last_clock[1] > self.STALL_TIMEOUT:
            run.abort_reason = f"simulated time stalled for {self.STALL_TIMEOUT:.0f} s"
            return True
        if now - run.last_print >= self.progress_period:
            run.last_print = now
            self.out(progress_line(w, self.prefix))
        return False

    #: wall s roslaunch gets to exit once every node it started is gone, after a user's
    #: signal: roslaunch ignores every signal after its first one, and while it is still
    #: starting the master it keeps waiting for it (up to 10 s) after its nodes are gone
    ORPHAN_GRACE = 1.0
    #: wall s for an orderly shutdown after a user's signal; before GO, when no node has
    #: anything to save and a node busy starting (a navigation function computed in C)
    #: cannot handle a signal until it is done, the shorter one, then the tree is stopped
    #: with short waits: a Ctrl-C during start-up ends the runner within about 5 s
    USER_STOP_WAIT, USER_STOP_WAIT_BEFORE_GO = 6.0, 2.0

    def _shutdown(self, proc, tree, before_go=False):
        """Orderly shutdown: SIGINT to roslaunch, which stops the nodes (the monitor writes
        its files); a second signal from the user makes it hard; then make sure nothing of
        ours survives, naming what had to be killed."""
        tree.refresh()
        if proc.poll() is None:
            try:
                os.kill(proc.pid, signal.SIGINT)
            except OSError:
                pass
            self._wait_for_roslaunch(proc, tree, before_go)
        user = signal_name(self._stop_requested())
        hurry = user and before_go
        hard = tree.stop(grace=0.5 if hurry else 1.0 if user else 3.0,
                         term_wait=1.0 if hurry else 3.0)
        if hard:
            self.out(f"warning: killed {len(hard)} process(es) that ignored SIGINT/SIGTERM: "
                     f"{tree.describe(hard)}")
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            pass

    def _wait_for_roslaunch(self, proc, tree, before_go):
        """After the SIGINT to roslaunch: wait for it to exit, up to 20 s (after a user's
        signal :data:`USER_STOP_WAIT` s, before GO :data:`USER_STOP_WAIT_BEFORE_GO` s; then
        the caller stops what is left). After a user's signal, roslaunch alone (its nodes
        gone) gets :data:`ORPHAN_GRACE` s, then it is killed and named."""
        def user_wait():
            return self.USER_STOP_WAIT_BEFORE_GO if before_go else self.USER_STOP_WAIT
        first = self._stop_requested()
        deadline = time.monotonic() + (user_wait() if signal_name(first) else 20)
        orphan_since = None
        while proc.poll() is None and time.monotonic() < deadline:
            try:
                time.sleep(0.2)
                tree.refresh()
            except KeyboardInterrupt:
                self.request_stop("SIGINT")
                break
            if first is None and self._stop_requested():
                first = self._stop_requested()
                deadline = min(deadline, time.monotonic() + user_wait())
            if signal_name(first) and tree.alive() == [proc.pid]:
                orphan_since = orphan_since or time.monotonic()
                if time.monotonic() - orphan_since >= self.ORPHAN_GRACE:
                    self.out("warning: killed roslaunch (pid %d): its nodes had stopped but it "
                             "kept waiting (it was still starting up)" % proc.pid)
                    proc.kill()
                    return

    def _finalise(self, run):
        """Decide the status (:mod:`.outcome`), record it in info.csv and
        ``<prefix>_run.yaml``, build the Outcome."""
        cfg = self.cfg
        wall = time.monotonic() - run.t_start
        info = read_info(self.prefix)
        stop = self._stop_requested()
        monitor_record = rs.read_run_yaml(self.prefix) or {}
        record = decide_status(stop, run.crash, run.abort_reason, info, monitor_record)
        record["longest_silence"] = monitor_record.get("longest_silence") or []
        warning = rs.silence_warning(record["longest_silence"], cfg.dead_robot_timeout)
        if warning:
            self.out(f"warning: {warning}")
        status = record["status"]
        code = rs.exit_code_for(status, signal_name(stop))
        missing = missing_files(self.prefix)
        if missing and code == rs.EXIT_OK:
            status, code = rs.ABORTED, rs.EXIT_FAILED
            record.update(status=status, reason=f"missing result files: {', '.join(missing)}")
        full = no_space_record(self.prefix, record, missing)
        if full:
            record, status, code = full, full["status"], rs.exit_code_for(full["status"])
        if info is not None:
            rs.set_info_status(self.prefix, status)
        sim, _, pace = timing(info, run.watcher, run.go_wall, wall)
        last_status = getattr(run.watcher, "status", None) or {}
        record.update(
            sim_time=round(sim, 1) if sim is not None else 0.0,
            wall_time=round(wall, 1), go_after=round(run.go_wall, 1)
            if run.go_wall is not None else None, pace=round(pace, 2) if pace else None,
            exit_code=code, files_complete=not missing and info is not None,
            missing_files=missing,
            requested={"timeout": cfg.timeout, "cycles": cfg.cycles,
                       "dead_robot_timeout": cfg.dead_robot_timeout},
            clock=clock_record(last_status, cfg.speedup or "auto", pace), written_by="runner")
        try:
            rs.write_run_yaml(self.prefix, record)
        except OSError as e:
            self.out(f"warning: cannot write {self.prefix}_run.yaml ({e.strerror}); its record "
                     "is on the result line below")
        files = [f"{self.prefix}_{s}" for s in RESULT_SUFFIXES]
        return Outcome(code, summary(status, record, cfg.dead_robot_timeout), self.prefix,
                       [f for f in files if os.path.isfile(f)], sim or 0.0, wall, run.go_wall,
                       status, record)
