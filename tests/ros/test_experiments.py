"""Full-stack experiments through scripts/start_experiments.py: simulator, navigation,
agents and monitor, each run with its own master (issue 6 acceptance)."""
import glob
import os
import signal
import subprocess
import sys
import time

import pytest

from rosenv import ros_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
from patrolling_sim.results import parse_info_line  # noqa: E402

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


def test_headless_run_to_timeout(tmp_path):
    p = start(["--map", "grid", "--robots", "2", "--alg", "CGG", "--loc", "fake_localization",
               "--timeout", "90", "--speedup", "4"], tmp_path)
    rc, out = finish(p, 300)
    assert rc == 0, out[-3000:]
    assert "progress: sim" in out and "results: " in out
    (prefix,) = prefixes(tmp_path)
    info, rows = check_files(prefix)
    assert info["termination"] == "TIMEOUT" and info["algorithm"] == "CGG"
    assert info["team_size"] == 2 and info["nav_module"] == "spqrel_nav_lite"
    assert 89.0 <= info["sim_duration"] <= 100.0
    assert len(rows) >= 4, "robots hardly moved:\n" + out[-2000:]
    # robots really drive: a grid edge is 5.7 m, nav speed <= 1 m/s -> idleness >= 5.7 s
    assert min(float(r.split(";")[3]) for r in rows) >= 5.0
    assert os.path.isdir(prefix + "_logs") and os.listdir(prefix + "_logs")
    assert master_ports_closed(out)


def test_ctrl_c_keeps_complete_files(tmp_path):
    p = start(["--map", "grid", "--robots", "2", "--alg", "CR", "--loc", "fake_localization",
               "--timeout", "0", "--speedup", "3"], tmp_path)
    t0 = time.time()
    seen = ""
    while time.time() - t0 < 150:               # wait for GO and a few visits
        line = p.stdout.readline()
        seen += line
        if "progress:" in line and "go yes" in line and "visits 0" not in line:
            break
    else:
        os.killpg(p.pid, signal.SIGKILL)
        pytest.fail("no visits before the deadline:\n" + seen[-2000:])
    p.send_signal(signal.SIGINT)
    rc, out = finish(p, 90)
    out = seen + out
    assert rc == 130, out[-3000:]
    (prefix,) = prefixes(tmp_path)
    info, _ = check_files(prefix)
    assert info["total_visits"] >= 0 and info["sim_duration"] > 0
    assert master_ports_closed(out)


def test_original_positional_form_with_amcl(tmp_path):
    # MAP NROBOTS INITPOS ALG LOC NAV GWAIT COMMDELAY TERM TIMEOUT [CUSTOM_STAGE] [SPEEDUP]
    p = start(["1r5", "1", "default", "CR", "AMCL", "spqrel_navigation", "0", "0", "xterm",
               "60", "false", "3"], tmp_path)
    rc, out = finish(p, 300)
    assert rc == 0, out[-3000:]
    (prefix,) = prefixes(tmp_path)
    info, rows = check_files(prefix)
    assert info["team_size"] == 1 and info["termination"] == "TIMEOUT"
    assert info["total_visits"] >= 1 and rows, out[-2000:]      # a vertex was revisited


def test_bad_arguments_start_nothing(tmp_path):
    for args, needle in ((["--map", "atlantis", "--robots", "2", "--alg", "CR"], "atlantis"),
                         (["--map", "grid", "--robots", "2", "--alg", "NOPE"], "--alg"),
                         (["grid", "2", "default", "CR"], "needs 10 to 12 arguments")):
        r = subprocess.run(["/usr/bin/python3", START, *args, "--results-dir", str(tmp_path)],
                           capture_output=True, text=True, env=ros_env(), timeout=60)
        assert r.returncode == 2, (args, r.stderr)
        assert needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not glob.glob(f"{tmp_path}/**/*_config.yaml", recursive=True)
