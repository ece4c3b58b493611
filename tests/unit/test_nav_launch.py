"""launch/robot.launch and spqrel_nav_lite's robot_nav.launch resolve to the right nodes for
each localisation / navigation mode (roslaunch --nodes parses the XML; no master needed)."""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
LAUNCH = os.path.join(ROOT, "src", "patrolling_sim", "launch", "robot.launch")

pytestmark = pytest.mark.skipif(shutil.which("roslaunch", path="/usr/bin") is None,
                                reason="roslaunch not installed")


def roslaunch_query(option, *args):
    """stdout of ``roslaunch OPTION robot.launch ARGS`` (an option that only inspects)."""
    env = dict(os.environ, ROS_PACKAGE_PATH=os.path.join(ROOT, "src"),
               PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))
    proc = subprocess.run(["/usr/bin/roslaunch", option, LAUNCH, *args], env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def nodes(*args):
    return sorted(roslaunch_query("--nodes", *args).split())


def test_amcl_mode():
    assert nodes("robotname:=robot_3", "localization:=AMCL") == ["/robot_3/robot_nav"]
    assert nodes("robotname:=robot_3", "localization:=AMCL", "combined:=false") == \
        ["/robot_3/amcl", "/robot_3/move_base"]


def test_fake_localization_mode():
    assert nodes("robotname:=robot_0", "localization:=fake_localization") == \
        ["/robot_0/robot_nav"]
    assert nodes("robotname:=robot_0", "localization:=fake_localization",
                 "combined:=false") == ["/robot_0/fake_localization", "/robot_0/move_base"]


def params(*args):
    """{name: value} of the parameters roslaunch would set (``roslaunch --dump-params``)."""
    import yaml
    return yaml.safe_load(roslaunch_query("--dump-params", *args))


@pytest.mark.parametrize("combined", ["true", "false"])
def test_parameters_live_where_the_standalone_nodes_read_them(combined):
    """robot_nav reads amcl's and move_base's parameters from <ns>/amcl and <ns>/move_base,
    so both modes set the very same parameters."""
    p = params("robotname:=robot_2", "localization:=AMCL", "x:=1.5", "y:=2.5", "yaw:=0.5",
               "map_yaml:=/m.yaml", f"combined:={combined}")
    assert p["/robot_2/amcl/initial_pose_x"] == 1.5
    assert p["/robot_2/amcl/initial_pose_a"] == 0.5
    assert p["/robot_2/amcl/odom_frame_id"] == "robot_2/odom"
    assert p["/robot_2/move_base/map_yaml"] == "/m.yaml"
    assert p["/robot_2/actionlib_status_frequency"] == 1.0
    assert ("/robot_2/robot_nav/localization" in p) == (combined == "true")


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
