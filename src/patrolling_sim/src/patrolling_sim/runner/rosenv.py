"""The environment ROS processes of this workspace need, built once from devel/setup.bash.

Debian's ROS helpers use ``/usr/bin/env python3``; the first ``python3`` on PATH may be
another interpreter without rospy, so ``/usr/bin`` is put first.
"""
import functools
import os
import socket
import subprocess

from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError


@functools.lru_cache(maxsize=1)
def workspace_env():
    """Environment of ``source`` the workspace's setup.bash
    (:func:`patrolling_sim.common.paths.workspace_setup`) with /usr/bin first on PATH."""
    setup = paths.workspace_setup()
    if not os.path.isfile(setup):
        raise PatrolInputError(f"{setup} not found: build the workspace first (make setup)")
    return sourced_env(setup)


def sourced_env(setup):
    """Environment of ``source SETUP`` (a catkin workspace's devel/setup.bash) with /usr/bin
    first on PATH and no ROS_MASTER_URI (a new dict on every call)."""
    out = subprocess.run(["bash", "-c", f"source '{setup}' && env -0"], check=True,
                         capture_output=True).stdout
    env = dict(kv.split("=", 1) for kv in out.decode().split("\0") if "=" in kv)
    env["PATH"] = "/usr/bin:/bin:" + env.get("PATH", "")
    env.pop("ROS_MASTER_URI", None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def free_port():
    """A TCP port that was free a moment ago (the master binds it right after)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def experiment_env(port, log_dir, ros_home=None):
    """Environment for one experiment: its own master on ``port``, logs in ``log_dir``."""
    env = dict(workspace_env())
    env["ROS_MASTER_URI"] = f"http://127.0.0.1:{port}"
    env["ROS_IP"] = "127.0.0.1"
    env.pop("ROS_HOSTNAME", None)
    env["ROS_LOG_DIR"] = log_dir
    env["ROS_HOME"] = ros_home or log_dir
    return env
