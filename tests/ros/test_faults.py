"""Fault injection on short full-stack runs (grid, 2 robots, fake localisation, speed-up 5):
kill a node the experiment needs, signal the runner at every stage, kill the runner.

Each case checks the runner's exit code, the status recorded in info.csv and
``<prefix>_run.yaml``, the named culprit, the result files (complete where results existed)
and that no process of the run is left. The run's processes are found as the descendants
of the runner's pid (remembered with their start times while the run goes on), never by
name; a node to kill is picked among them by its ``__name:=`` argument.
"""
import glob
import os
import signal
import subprocess
import sys
import time

import pytest
import yaml

from rosenv import ros_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
from patrolling_sim.monitor.results import parse_info_line  # noqa: E402
from patrolling_sim.runner.proctree import ProcessTree  # noqa: E402

RUN = ["--map", "grid", "--robots", "2", "--alg", "CR", "--loc", "fake_localization",
       "--timeout", "0", "--speedup", "5"]
FOUR = ("idleness.csv", "timeresults.csv", "results.txt", "info.csv")


class Run:
    """The runner in its own session, its output read line by line, its process tree
    followed."""

    def __init__(self, tmp_path, extra=(), preexec_fn=None):
        self.tmp = tmp_path
        self.p = subprocess.Popen(["/usr/bin/python3", START, *RUN, *extra, "--results-dir",
                                   str(tmp_path)], stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, env=ros_env(),
                                  cwd=str(tmp_path), start_new_session=True,
                                  preexec_fn=preexec_fn)
        self.tree = ProcessTree(self.p.pid)
        self.out = ""
        os.set_blocking(self.p.stdout.fileno(), False)

    def _read(self):
        while True:
            try:
                chunk = os.read(self.p.stdout.fileno(), 65536)
            except BlockingIOError:
                return
            except (OSError, ValueError):
                return
            if not chunk:
                return
            self.out += chunk.decode(errors="replace")

    def wait_for(self, text, limit=240):
        """Read output until ``text`` appears (the limit only keeps a broken run from
        hanging the suite; judged by what the run prints, not by time)."""
        t0 = time.monotonic()
        while text not in self.out:
            self._read()
            self.tree.refresh()
            if self.p.poll() is not None:
                self._read()
                if text in self.out:
                    break
                self.cleanup()
                pytest.fail(f"run ended before '{text}':\n{self.out[-3000:]}")
            if time.monotonic() - t0 > limit:
                self.cleanup()
                pytest.fail(f"no '{text}':\n{self.out[-3000:]}")
            time.sleep(0.1)

    def visits(self):
        """Wait until the progress line shows visits (results exist)."""
        t0 = time.monotonic()
        while True:
            self.wait_for("go yes")
            last = [ln for ln in self.out.splitlines() if ln.startswith("progress:")][-1]
            if "go yes" in last and "visits 0 " not in last:
                return
            if time.monotonic() - t0 > 240:
                self.cleanup()
                pytest.fail("no visit:\n" + self.out[-3000:])
            time.sleep(0.5)
            self._read()

    def node_pid(self, name):
        """Pid of the node ``name`` (``ns/name`` for a namespaced node; ``master`` for
        rosmaster) among the runner's descendants."""
        self.tree.refresh()
        for pid in self.tree.alive():
            try:
                with open(f"/proc/{pid}/cmdline", "rb") as f:
                    args = f.read().decode(errors="replace").split("\0")
            except OSError:
                continue
            ns, _, base = name.rpartition("/")
            if f"__name:={base}" in args and (not ns or any(
                    a.startswith("__log:=") and f"/{ns}-{base}-" in a for a in args)):
                return pid          # a namespaced node: roslaunch names its log ns-name-k
            if name == "master" and any(a.endswith("rosmaster") for a in args):
                return pid
        pytest.fail(f"no process of node {name} in the run:\n{self.out[-2000:]}")

    def finish(self, limit=120):
        t0 = time.monotonic()
        while self.p.poll() is None and time.monotonic() - t0 < limit:
            self._read()
            self.tree.refresh()
            time.sleep(0.2)
        if self.p.poll() is None:
            self.cleanup()
            pytest.fail("the runner did not end:\n" + self.out[-3000:])
        os.set_blocking(self.p.stdout.fileno(), True)
        self.out += self.p.stdout.read().decode(errors="replace")
        return self.p.returncode

    def left(self, limit=30):
        """Processes of the run still alive once it ended (waits for them to go)."""
        t0 = time.monotonic()
        while self.tree.alive() and time.monotonic() - t0 < limit:
            time.sleep(0.3)
        return self.tree.alive()

    def cleanup(self):
        self.tree.refresh()
        for pid in self.tree.alive():
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass

    def prefix(self):
        (cfg,) = glob.glob(f"{self.tmp}/**/*_config.yaml", recursive=True)
        return cfg[:-len("_config.yaml")]


def check_end(run, code, status, *, culprit=None, robot=None, complete_files=True,
              signal_name=None):
    rc = run.finish()
    out = run.out
    left = run.left()
    run.cleanup()
    assert not left, f"{len(left)} processes of the run survived:\n{out[-2000:]}"
    assert rc == code, f"exit {rc}, expected {code}:\n{out[-3000:]}"
    assert "Traceback" not in out, out[-3000:]
    prefix = run.prefix()
    rec = yaml.safe_load(open(prefix + "_run.yaml"))
    assert rec["status"] == status and rec["written_by"] == "runner", rec
    assert rec["exit_code"] == code and rec["complete"] is False, rec
    assert f"result: {status}" in out, out[-2000:]
    if culprit:
        assert rec["culprit"]["node"].split("-")[0] == culprit, rec
        assert rec["culprit"]["robot"] == robot, rec
        assert rec["culprit"]["description"] in out, out[-2000:]
    if signal_name:
        assert rec["signal"] == signal_name, rec
    present = [s for s in FOUR if os.path.isfile(f"{prefix}_{s}")]
    if complete_files:
        assert present == list(FOUR), present
        info = parse_info_line(open(prefix + "_info.csv").read())
        assert info["termination"] == status, info
        assert info["sim_duration"] > 0, info
        assert rec["sim_time"] > 0
    return rec, prefix


@pytest.mark.parametrize("node,extra,culprit,robot", [
    ("stage2d", (), "stage2d", None),
    ("master", (), "master", None),
    ("robot_0/robot_nav", (), "robot_0/robot_nav", 0),
    ("patrol_robot1", ("--processes", "separate"), "patrol_robot1", 1),
])
def test_killed_node_ends_the_run_as_crashed(tmp_path, node, extra, culprit, robot):
    run = Run(tmp_path, extra)
    # killed soon after GO, once simulated time ran on (the simulator holds its clock for
    # 0.5 wall s at GO): the monitor has results to keep
    run.wait_for("go yes")
    pid = run.node_pid(node)
    os.kill(pid, signal.SIGKILL)
    rec, _ = check_end(run, 3, "CRASHED", culprit=culprit, robot=robot)
    assert rec["culprit"]["exit_code"] == -9, rec
    if robot is not None:
        assert f"robot {robot}'s" in rec["reason"], rec


def test_killed_monitor_crashed_without_info(tmp_path):
    run = Run(tmp_path)
    run.wait_for("GO after")
    os.kill(run.node_pid("monitor"), signal.SIGKILL)
    rec, prefix = check_end(run, 3, "CRASHED", culprit="monitor", complete_files=False)
    # the monitor had no chance to write info.csv; what it measured is kept
    assert not os.path.exists(prefix + "_info.csv")
    assert [m[-len("info.csv"):] for m in rec["missing_files"]] == ["info.csv"], rec
    rows = open(prefix + "_idleness.csv").read().splitlines()
    assert rows[0].startswith("Time;Robot")


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_mid_run_interrupted_with_complete_files(tmp_path, sig, code):
    # started with SIGINT ignored, as `cmd &` in a script does: the runner must still obey it
    run = Run(tmp_path, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    run.visits()
    run.p.send_signal(sig)
    rec, prefix = check_end(run, code, "INTERRUPTED", signal_name=sig.name)
    info = parse_info_line(open(prefix + "_info.csv").read())
    assert info["total_visits"] >= 1 and rec["pace"] > 0


def test_sigint_before_go(tmp_path):
    run = Run(tmp_path)
    run.wait_for("experiment: ")
    run.p.send_signal(signal.SIGINT)
    rec, prefix = check_end(run, 130, "INTERRUPTED", signal_name="SIGINT",
                            complete_files=False)
    info = open(prefix + "_info.csv").read() if os.path.exists(prefix + "_info.csv") else None
    if info:        # the monitor had started: its (empty) measurements are marked
        assert parse_info_line(info)["termination"] == "INTERRUPTED"


#: s from a SIGINT during start-up to the runner's exit that tells the behaviours apart:
#: waiting out roslaunch (which ignores signals after its first one while it waits for the
#: master it was starting) and a node busy starting took 6 s plus 4 s of signals to the
#: process tree; before GO the runner now waits 2 s, then signals with short waits (at most
#: about 4 s in all, 1.5 s when only roslaunch lingers); the rest is a loaded machine's margin
EARLY_STOP_BOUND = 8.0


@pytest.mark.parametrize("delay", [0.3, 1.0, 1.5, 2.0])
def test_early_sigint_stops_at_once(tmp_path, delay):
    """SIGINT during imports / validation / launch (the master and the nodes starting):
    exit 130, one line, nothing left, no unnamed SIGKILL. (A run whose launch had begun
    records INTERRUPTED in its run.yaml.)"""
    # started with the signals held, as the batch starts its runs: on a loaded machine the
    # interpreter's own start (before any line of the program) can outlast the delay
    run = Run(tmp_path, preexec_fn=lambda: signal.pthread_sigmask(
        signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM}))
    time.sleep(delay)           # the moment of the signal is the test input, not a bound
    run.p.send_signal(signal.SIGINT)
    t_signal = time.monotonic()
    rc = run.finish()
    stopped_after = time.monotonic() - t_signal
    assert stopped_after < EARLY_STOP_BOUND, f"{stopped_after:.1f} s:\n{run.out}"
    for line in run.out.splitlines():
        if "killed" in line:        # whatever had to be killed is named with its pid
            assert "(pid " in line, run.out
    left = run.left()
    run.cleanup()
    assert not left, run.out
    assert rc == 130, run.out
    assert "Traceback" not in run.out, run.out
    cfgs = glob.glob(f"{tmp_path}/**/*_config.yaml", recursive=True)
    if cfgs:
        rec = yaml.safe_load(open(cfgs[0][:-len("_config.yaml")] + "_run.yaml"))
        assert rec["status"] == "INTERRUPTED" and rec["exit_code"] == 130
    else:
        assert "interrupted by SIGINT" in run.out, run.out


def test_killed_runner_leaves_no_process_and_marks_the_run(tmp_path):
    """SIGKILL gives the runner no chance: roslaunch gets SIGTERM from the kernel
    (parent-death signal) and stops every node; the monitor marks the run INTERRUPTED."""
    run = Run(tmp_path)
    run.wait_for("GO after")
    assert len(run.tree.alive()) >= 5
    run.p.kill()
    run.finish()
    left = run.left()
    run.cleanup()
    assert not left, f"{len(left)} processes outlived the killed runner"
    prefix = run.prefix()
    info = parse_info_line(open(prefix + "_info.csv").read())
    assert info["termination"] == "INTERRUPTED"
    rec = yaml.safe_load(open(prefix + "_run.yaml"))
    assert rec["status"] == "INTERRUPTED" and rec["written_by"] == "monitor"
    assert rec["exit_code"] is None and rec["complete"] is False


def test_silent_robot_fails_naming_it(tmp_path):
    """``--dead-robot-timeout``: robot 1's agent is frozen (SIGSTOP, so its process does not
    die): robot 1 sends no visit, and after 15 sim s the monitor ends the run with FAIL
    naming robot 1; the runner exits 1 and records the robot ids."""
    run = Run(tmp_path, ("--processes", "separate", "--dead-robot-timeout", "15"))
    run.wait_for("go yes")
    pid = run.node_pid("patrol_robot1")
    os.kill(pid, signal.SIGSTOP)
    try:
        prefix = run.prefix()
        t0 = time.monotonic()
        while not os.path.exists(prefix + "_info.csv") and run.p.poll() is None and \
                time.monotonic() - t0 < 240:
            run._read()
            run.tree.refresh()
            time.sleep(0.2)
    finally:
        os.kill(pid, signal.SIGCONT)      # let it stop with the others
    rec, prefix = check_end(run, 1, "FAIL")
    assert rec["robots"] == [1], rec
    assert "robot(s) 1 sent no visit for 15 sim s" in run.out, run.out[-2000:]
    info = parse_info_line(open(prefix + "_info.csv").read())
    assert info["termination"] == "FAIL" and 15.0 <= info["sim_duration"] < 40.0, info


def test_interrupted_batch_prints_its_table(tmp_path):
    """SIGINT to a batch while its first run starts: the run is stopped, the table lists it
    as interrupted and the others as never started, the batch's temporary files go."""
    batch = tmp_path / "b.yaml"
    batch.write_text("base: {map: grid, robots: 2, loc: fake_localization, timeout: 600}\n"
                     "grid: {alg: [CR, CGG, RAND]}\n")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(ros_env(), TMPDIR=str(tmp))
    p = subprocess.Popen(["/usr/bin/python3", START, "--batch", str(batch), "--results-dir",
                          str(tmp_path / "res"), "--speedup", "5"], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, env=env, start_new_session=True)
    tree = ProcessTree(p.pid)
    t0 = time.monotonic()
    while not any(os.path.exists(f"{r}/run_0.out") for r, _, _ in os.walk(tmp)):
        assert p.poll() is None and time.monotonic() - t0 < 120, "the batch did not start"
        time.sleep(0.1)
    tree.refresh()
    p.send_signal(signal.SIGINT)
    out, _ = p.communicate(timeout=120)
    out = out.decode(errors="replace")
    t0 = time.monotonic()
    while tree.alive() and time.monotonic() - t0 < 30:
        time.sleep(0.3)
    left = tree.alive()
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert not left, out
    assert p.returncode == 130, out
    rows = [ln.split() for ln in out.splitlines() if ln.strip()[:1].isdigit()]
    assert [r[0] for r in rows] == ["1", "2", "3"], out
    assert rows[0][5] == "130" and rows[1][-2:] == rows[2][-2:] == ["never", "started"], out
    assert "Traceback" not in out, out
    assert os.listdir(tmp) == [], "the batch's temporary files were left"
