"""launch/robot.launch and spqrel_nav_lite's robot_nav.launch resolve to the right nodes for
each localisation / navigation mode (roslaunch --nodes parses the XML; no master needed)."""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
LAUNCH = os.path.join(ROOT, "launch", "robot.launch")

pytestmark = pytest.mark.skipif(shutil.which("roslaunch", path="/usr/bin") is None,
                                reason="roslaunch not installed")


def nodes(*args):
    env = dict(os.environ, ROS_PACKAGE_PATH=os.path.join(ROOT, "src"),
               PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))
    proc = subprocess.run(["/usr/bin/roslaunch", "--nodes", LAUNCH, *args], env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return sorted(proc.stdout.split())


def test_amcl_mode():
    assert nodes("robotname:=robot_3", "localization:=AMCL") == \
        ["/robot_3/amcl", "/robot_3/move_base"]


def test_fake_localization_mode():
    assert nodes("robotname:=robot_0", "localization:=fake_localization") == \
        ["/robot_0/fake_localization", "/robot_0/move_base"]


def test_ros_navigation_mode_uses_the_real_packages():
    env = dict(os.environ, ROS_PACKAGE_PATH=os.path.join(ROOT, "src"))
    assert nodes("navigation:=ros") == ["/robot_0/amcl", "/robot_0/move_base"]
    # the real amcl is not packaged in Debian 12: resolving its executable fails clearly
    proc = subprocess.run(["/usr/bin/roslaunch", "--args", "/robot_0/amcl", LAUNCH,
                           "navigation:=ros"], env=env, capture_output=True, text=True,
                          timeout=60)
    if shutil.which("amcl", path="/opt/ros/noetic/lib/amcl") is None:
        assert "amcl" in (proc.stdout + proc.stderr)
        assert "spqrel_nav_lite" not in proc.stdout
