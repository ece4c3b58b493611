"""A map in a folder whose path holds a space runs on the full stack (the launch file quotes
the path it passes to the map server in ``args``, which roslaunch splits as a shell does)."""
import glob
import os
import shutil
import subprocess

from rosenv import ros_env

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
START = os.path.join(ROOT, "scripts", "start_experiments.py")


def test_full_stack_on_a_map_whose_folder_has_a_space(tmp_path):
    maps = tmp_path / "my maps" / "grid"
    shutil.copytree(os.path.join(ROOT, "maps", "grid"), maps)
    out = tmp_path / "results with space"
    r = subprocess.run(["/usr/bin/python3", START, "--headless", "--map",
                        str(maps / "grid.yaml"), "--robots", "2", "--alg", "CR",
                        "--timeout", "40", "--speedup", "4", "--results-dir", str(out)],
                       env=ros_env(), capture_output=True, text=True, timeout=300,
                       start_new_session=True, stdin=subprocess.DEVNULL)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    infos = glob.glob(f"{out}/**/*_info.csv", recursive=True)
    assert len(infos) == 1 and "TIMEOUT" in open(infos[0]).read()
