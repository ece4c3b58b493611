"""The workspace installs (``catkin_make install``) and an experiment runs from the install
space alone: the runner, the nodes, the launch files, the data and every subpackage come from
``install/``, in an environment that holds nothing of the source checkout."""
import glob
import os
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
INSTALL = os.path.join(ROOT, "install")


def _install_env():
    """A clean environment: only ``install/setup.bash`` on top of a minimal PATH and HOME."""
    return {"HOME": os.environ.get("HOME", "/root"), "PATH": "/usr/bin:/bin",
            "LANG": "C.UTF-8"}


def _in_install(command, timeout):
    """Run ``command`` (a bash string) after ``source install/setup.bash``; returns the
    completed process (stdout and stderr together)."""
    return subprocess.run(["bash", "-c", f"source '{INSTALL}/setup.bash' && {command}"],
                          env=_install_env(), cwd="/", capture_output=True, text=True,
                          timeout=timeout, start_new_session=True)


@pytest.fixture(scope="module")
def installed():
    """``catkin_make install`` of the built workspace (nothing to compile after make setup)."""
    r = subprocess.run(["catkin_make", "install", "-DPYTHON_EXECUTABLE=/usr/bin/python3",
                        "-DCMAKE_BUILD_TYPE=Release"], cwd=ROOT, capture_output=True,
                       text=True, timeout=900,
                       env=dict(os.environ, PATH="/usr/bin:/bin:/usr/sbin:/sbin"))
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    return INSTALL


def test_the_install_space_holds_the_package_and_its_data(installed):
    r = _in_install("/usr/bin/python3 -c 'import patrolling_sim.common.paths as p, "
                    "patrolling_sim.campaign.engine, spqrel_nav_lite.planner as q; "
                    "print(p.__file__); print(q.__file__); print(p.data_root()); "
                    "print(p.program(\"start_experiments.py\"))'", timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
    paths = r.stdout.split()
    assert all(p.startswith(installed + os.sep) for p in paths), paths
    data = paths[2]
    for f in ("maps/grid/grid.yaml", "maps/grid/grid.graph", "params/initial_poses.txt",
              "launch/robot.launch", "launch/patrol.rviz"):
        assert os.path.isfile(os.path.join(data, f)), f
    assert os.access(paths[3], os.X_OK)


def test_an_experiment_runs_from_the_install_space(installed, tmp_path):
    """The full stack (simulator, navigation, agents, monitor) started by the installed
    runner: TIMEOUT, complete result files, a launch file naming no source path."""
    out = tmp_path / "results"
    r = _in_install(f"/usr/bin/python3 {installed}/lib/patrolling_sim/start_experiments.py "
                    f"--headless --map grid --robots 2 --alg CR --timeout 60 --speedup 4 "
                    f"--results-dir {out}", timeout=300)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    infos = glob.glob(f"{out}/**/*_info.csv", recursive=True)
    assert len(infos) == 1, r.stdout[-2000:]
    prefix = infos[0][:-len("_info.csv")]
    for suffix in ("idleness.csv", "timeresults.csv", "results.txt", "run.yaml"):
        assert os.path.isfile(f"{prefix}_{suffix}"), suffix
    assert "TIMEOUT" in open(infos[0]).read()
    launch = open(prefix + "_experiment.launch").read()
    assert "$(find patrolling_sim)/launch/robot.launch" in launch
    assert os.path.join(ROOT, "src") not in launch and os.path.join(ROOT, "launch") not in launch
