"""Inputs that used to fail late now fail before anything starts, in one line with exit 2:
an interpreter without the packages a program needs, --rviz / --gui-sim without a display,
a map whose name holds a space."""
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPTS = os.path.join(ROOT, "scripts")


def _run(args, env=None, cwd=None):
    return subprocess.run(args, capture_output=True, text=True, env=env, cwd=cwd,
                          stdin=subprocess.DEVNULL, timeout=120)


def _one_line_exit_2(r):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    return lines[0]


@pytest.mark.parametrize("program, module", [("start_experiments.py", "rospy"),
                                             ("report.py", "pandas"),
                                             ("campaign.py", "distributed")])
def test_an_interpreter_without_what_the_program_needs(tmp_path, program, module):
    """``python3 -S`` stands for an interpreter without Debian's packages (the default
    python3 on PATH here): the program says to use /usr/bin/python3 and starts nothing."""
    args = [sys.executable, "-S", os.path.join(SCRIPTS, program)]
    args += {"start_experiments.py": ["--headless", "--map", "grid", "--robots", "2",
                                      "--alg", "CR", "--results-dir", str(tmp_path / "r")],
             "report.py": [str(tmp_path)],
             "campaign.py": [str(tmp_path / "c.yaml"), "--out", str(tmp_path / "o")]}[program]
    line = _one_line_exit_2(_run(args, cwd=str(tmp_path)))
    assert f"cannot import {module}" in line and "/usr/bin/python3" in line
    assert not (tmp_path / "r").exists() and not (tmp_path / "o").exists()


def test_without_the_workspace_on_the_path():
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    line = _one_line_exit_2(_run([sys.executable, os.path.join(SCRIPTS, "graph_sim.py"),
                                  "--map", "grid"], env=env, cwd="/"))
    assert "source devel/setup.bash" in line


@pytest.mark.parametrize("flag", ["--rviz", "--gui-sim"])
def test_a_window_without_a_display(tmp_path, flag):
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    r = _run([sys.executable, os.path.join(SCRIPTS, "start_experiments.py"), "--headless",
              "--map", "grid", "--robots", "2", "--alg", "CR", flag,
              "--results-dir", str(tmp_path / "r")], env=env)
    line = _one_line_exit_2(r)
    assert f"argument {flag}: needs a display" in line
    assert not (tmp_path / "r").exists()


def test_a_map_name_with_a_space(tmp_path):
    src = os.path.join(ROOT, "maps", "grid")
    d = tmp_path / "my grid"
    d.mkdir()
    for f in os.listdir(src):
        shutil.copy(os.path.join(src, f), d / f.replace("grid", "my grid"))
    yaml_path = d / "my grid.yaml"
    yaml_path.write_text(yaml_path.read_text().replace("grid.", "my grid."))
    start = os.path.join(SCRIPTS, "start_experiments.py")
    line = _one_line_exit_2(_run([sys.executable, start, "--headless", "--map", str(yaml_path),
                                  "--robots", "2", "--alg", "CR",
                                  "--results-dir", str(tmp_path / "r")]))
    assert "holds a space" in line
