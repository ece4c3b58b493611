"""Full-stack experiments through scripts/start_experiments.py: simulator, navigation,
agents and monitor, each run with its own master."""
import glob
import os
import signal
import subprocess
import sys

import pytest

from rosenv import ros_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
from patrolling_sim.monitor.results import parse_info_line  # noqa: E402

SUFFIXES = ("idleness.csv", "timeresults.csv", "results.txt", "info.csv", "config.yaml",
            "experiment.launch")


def start(args, tmp_path, **kw):
    return subprocess.Popen(["/usr/bin/python3", START, *args, "--results-dir", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=ros_env(), cwd=str(tmp_path), start_new_session=True, **kw)


def finish(proc, timeout):
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        pytest.fail("experiment did not end in time:\n" + out[-3000:])
    return proc.returncode, out


def prefixes(tmp_path):
    return sorted(p[:-len("_info.csv")] for p in glob.glob(f"{tmp_path}/**/*_info.csv",
                                                           recursive=True))


def check_files(prefix):
    for suf in SUFFIXES:
        assert os.path.isfile(f"{prefix}_{suf}"), f"missing {prefix}_{suf}"
    info = parse_info_line(open(prefix + "_info.csv").read(), prefix + "_info.csv")
    with open(prefix + "_idleness.csv") as f:
        rows = f.read().splitlines()
    assert rows[0] == "Time;Robot;Node;Idleness;Interferences"
    return info, rows[1:]


def master_ports_closed(out):
    """The runner prints its master URI; nothing may listen there after the run."""
    import re
    import socket
    m = re.search(r"master http://127\.0\.0\.1:(\d+)", out)
    assert m, out[-2000:]
    s = socket.socket()
    try:
        return s.connect_ex(("127.0.0.1", int(m.group(1)))) != 0
    finally:
        s.close()


def own_processes(marker):
    """Pids whose command line mentions ``marker`` (the run's unique result prefix)."""
    pids = []
    for d in os.listdir("/proc"):
        if d.isdigit() and int(d) != os.getpid():
            try:
                with open(f"/proc/{d}/cmdline", "rb") as f:
                    if marker.encode() in f.read():
                        pids.append(int(d))
            except OSError:
                pass
    return pids


def check_complete_run(prefix, out, n_vertices, team_size, alg):
    """The acceptance checks of a finished run: files valid, >= 1 complete patrol cycle,
    every vertex visited, nothing of the run left running."""
    info, rows = check_files(prefix)
    assert info["termination"] == "TIMEOUT" and info["algorithm"] == alg, out[-2000:]
    assert info["team_size"] == team_size and info["nav_module"] == "spqrel_nav_lite"
    assert info["complete_cycles"] >= 1, f"no complete patrol cycle:\n{out[-2000:]}"
    visited = {int(r.split(";")[2]) for r in rows}
    assert visited == set(range(n_vertices)), f"never revisited: {set(range(n_vertices)) - visited}"
    assert {int(r.split(";")[1]) for r in rows} <= set(range(team_size))
    # robots really drive: a grid edge is 5.7 m, the goal tolerance 0.4 m and the
    # navigation goes <= 1 m/s, so one robot's reports are >= 4.9 s apart
    for rid in range(team_size):
        times = [float(r.split(";")[0]) for r in rows if int(r.split(";")[1]) == rid]
        assert all(b - a >= 4.0 for a, b in zip(times, times[1:])), (rid, times)
    assert os.path.isdir(prefix + "_logs") and os.listdir(prefix + "_logs")
    # no node printed a traceback, also not while the run stopped (late move_base
    # feedback reaching an agent that is shutting down must not raise)
    with open(os.path.join(prefix + "_logs", "roslaunch.log"), errors="replace") as f:
        log = f.read()
    assert "Traceback" not in log, log[max(0, log.find("Traceback") - 300):][:3000]
    assert master_ports_closed(out)
    assert own_processes(prefix) == [], "processes of the run survived"
    return info


def test_cgg_four_robots_full_stack(tmp_path):
    p = start(["--map", "grid", "--robots", "4", "--alg", "CGG", "--loc", "fake_localization",
               "--timeout", "300", "--speedup", "5"], tmp_path)
    rc, out = finish(p, 600)
    assert rc == 0, out[-3000:]
    assert "progress: sim" in out and "results: " in out
    (prefix,) = prefixes(tmp_path)
    info = check_complete_run(prefix, out, 25, 4, "CGG")
    assert 299.0 <= info["sim_duration"] <= 310.0


def test_parallel_runs_do_not_mix(tmp_path):
    """SEBS (4 robots, grid) and CR (1 robot, 1r5) at the same time, each with its own
    master: both finish, and neither sees the other's robots or messages."""
    a_dir, b_dir = tmp_path / "a", tmp_path / "b"
    a_dir.mkdir()
    b_dir.mkdir()
    a = start(["--map", "grid", "--robots", "4", "--alg", "SEBS", "--loc", "fake_localization",
               "--timeout", "300", "--speedup", "5"], a_dir)
    b = start(["--map", "1r5", "--robots", "1", "--alg", "CR", "--loc", "fake_localization",
               "--timeout", "120", "--speedup", "5"], b_dir)
    rc_b, out_b = finish(b, 600)
    rc_a, out_a = finish(a, 600)
    assert rc_a == 0, out_a[-3000:]
    assert rc_b == 0, out_b[-3000:]
    (pa,) = prefixes(a_dir)
    (pb,) = prefixes(b_dir)
    check_complete_run(pa, out_a, 25, 4, "SEBS")
    info_b, rows_b = check_files(pb)
    assert info_b["team_size"] == 1 and {r.split(";")[1] for r in rows_b} <= {"0"}
    assert all(0 <= int(r.split(";")[2]) < 12 for r in rows_b)     # 1r5 has 12 vertices
    import re
    ports = {re.search(r"master http://127\.0\.0\.1:(\d+)", o).group(1) for o in (out_a, out_b)}
    assert len(ports) == 2


def test_original_positional_form_with_amcl(tmp_path):
    # MAP NROBOTS INITPOS ALG LOC NAV GWAIT COMMDELAY TERM TIMEOUT [CUSTOM_STAGE] [SPEEDUP]
    p = start(["grid", "2", "default", "CGG", "AMCL", "spqrel_navigation", "0", "0", "xterm",
               "600", "false", "5"], tmp_path)
    rc, out = finish(p, 900)
    assert rc == 0, out[-3000:]
    (prefix,) = prefixes(tmp_path)
    check_complete_run(prefix, out, 25, 2, "CGG")


def test_bad_arguments_start_nothing(tmp_path):
    for args, needle in ((["--map", "atlantis", "--robots", "2", "--alg", "CR"], "atlantis"),
                         (["--map", "grid", "--robots", "2", "--alg", "NOPE"], "--alg"),
                         (["--map", "grid", "--robots", "0", "--alg", "CR"], "--robots"),
                         (["--map", "grid", "--robots", "two", "--alg", "CR"], "--robots"),
                         (["--map", "grid", "--robots", "2", "--alg", "CR", "--timeout", "-5"],
                          "--timeout"),
                         (["--map", "grid", "--robots", "2", "--alg", "CR", "--speedup", "0"],
                          "--speedup"),
                         (["grid", "2", "default", "CR", "AMCL", "ros", "x", "0", "xterm",
                           "60"], "GWAIT"),
                         (["grid", "2", "default", "CR"], "needs 10 to 12 arguments")):
        r = subprocess.run(["/usr/bin/python3", START, *args, "--results-dir", str(tmp_path)],
                           capture_output=True, text=True, env=ros_env(), timeout=60)
        assert r.returncode == 2, (args, r.stderr)
        assert needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not glob.glob(f"{tmp_path}/**/*_config.yaml", recursive=True)
    ro = tmp_path / "readonly"
    ro.mkdir()
    ro.chmod(0o500)
    r = subprocess.run(["/usr/bin/python3", START, "--map", "grid", "--robots", "1",
                        "--results-dir", str(ro / "sub")], capture_output=True, text=True,
                       env=ros_env(), timeout=60)
    if os.geteuid() != 0:                       # root may write anywhere
        assert r.returncode == 2 and "--results-dir" in r.stderr, r.stderr


# Ctrl-C, SIGTERM, a killed runner and crashed nodes: tests/ros/test_faults.py
