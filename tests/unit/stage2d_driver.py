"""A small C++ driver of one of patrol_stage2d's pure-logic headers, for the unit tests that
feed it event scripts (test_stage2d_reaction_hold.py, test_stage2d_go_hold.py)."""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
PKG = os.path.join(ROOT, "src", "patrol_stage2d")
CXX = shutil.which("g++") or shutil.which("c++")


def build(tmp_path_factory, name):
    """Compile ``src/patrol_stage2d/test/<name>.cpp`` (warnings are errors) and return
    ``run(header, events, rc=0)``: the driver fed the header line and one event per line,
    its exit status checked against ``rc``, its non-empty output lines returned. Skips the
    test without a C++ compiler."""
    if CXX is None:
        pytest.skip("no C++ compiler")
    exe = str(tmp_path_factory.mktemp(name) / name)
    subprocess.run([CXX, "-std=c++14", "-Wall", "-Wextra", "-Werror", "-O0",
                    "-I", os.path.join(PKG, "include"),
                    os.path.join(PKG, "test", name + ".cpp"), "-o", exe], check=True)

    def run(header, events, rc=0):
        p = subprocess.run([exe], input=header + "\n" + "\n".join(events) + "\n",
                           capture_output=True, text=True)
        assert p.returncode == rc, p.stderr
        return [line for line in p.stdout.split("\n") if line]
    return run
