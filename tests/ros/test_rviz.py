"""src/patrolling_sim/launch/patrol.rviz loads in rviz on a virtual screen and shows the map.

A master of our own on a free port; a small publisher sends the grid map on /map, patrol
graph markers and robot_0's pose; rviz runs under xvfb-run for ~10 s, then a screenshot of
the root window is taken (xwd) and converted (ImageMagick). Checks: the committed config is
what the generator produces, rviz prints no error, and the 3D view shows the map (many light
'free cell' pixels in the render area, not only the dark background). Skips only if rviz is
not installed.
"""
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CONFIG = os.path.join(ROOT, "src", "patrolling_sim", "launch", "patrol.rviz")
GENERATOR = os.path.join(ROOT, "scripts", "make_rviz_config.py")
SRC = os.path.join(ROOT, "src", "patrolling_sim", "src")

pytestmark = pytest.mark.skipif(shutil.which("rviz") is None, reason="rviz not installed")

PUBLISHER = r'''
import sys, math
sys.path.insert(0, sys.argv[1])
import rospy
from nav_msgs.msg import OccupancyGrid
from geometry_msgs.msg import PoseWithCovarianceStamped, Point
from visualization_msgs.msg import Marker, MarkerArray
from patrolling_sim.common import paths
from spqrel_nav_lite.mapio import load_map
from patrolling_sim.model.graph import load_graph

yaml_path, graph_path = paths.map_files("grid")
occ = load_map(yaml_path)
G = load_graph(graph_path, warn=False)
rospy.init_node("rviz_test_publisher")
grid = OccupancyGrid()
grid.header.frame_id = "map"
grid.info.resolution = occ.resolution
grid.info.width, grid.info.height = occ.width, occ.height
grid.info.origin.position.x, grid.info.origin.position.y = occ.origin[0], occ.origin[1]
grid.info.origin.orientation.w = 1.0
grid.data = occ.data.ravel().tolist()
pub_map = rospy.Publisher("/map", OccupancyGrid, queue_size=1, latch=True)
pub_mk = rospy.Publisher("/patrol_graph_markers", MarkerArray, queue_size=1, latch=True)
pub_pose = rospy.Publisher("/robot_0/amcl_pose", PoseWithCovarianceStamped, queue_size=1)
arr = MarkerArray()
for v in G.nodes:
    m = Marker()
    m.header.frame_id = "map"
    m.ns, m.id, m.type, m.action = "vertices", v, Marker.SPHERE, Marker.ADD
    m.pose.position.x, m.pose.position.y = G.nodes[v]["pos"]
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = m.scale.z = 0.8
    m.color.r, m.color.a = 1.0, 1.0
    arr.markers.append(m)
grid.header.stamp = rospy.Time.now()
pub_map.publish(grid)
pub_mk.publish(arr)
rate = rospy.Rate(5)
while not rospy.is_shutdown():
    p = PoseWithCovarianceStamped()
    p.header.frame_id = "map"
    p.header.stamp = rospy.Time.now()
    p.pose.pose.position.x, p.pose.pose.position.y = 1.425, 24.375
    p.pose.pose.orientation.w = 1.0
    p.pose.covariance[0] = p.pose.covariance[7] = 0.2
    pub_pose.publish(p)
    rate.sleep()
'''

SHOOT = r'''
rviz -d "$1" > "$2" 2>&1 &
P=$!
sleep "$4"
xwd -root -silent > "$3"
kill $P
wait $P
exit 0
'''


def rviz_errors(text):
    """Error lines of an rviz log, without the ones known to be harmless on this platform:
    rospack's lookup of the absent media_export package, and Mesa's software GL (Xvfb)
    refusing to link rviz's 8-bit image shader (rviz falls back; the map is still drawn,
    which the tests check on the screenshot)."""
    return [line for line in text.splitlines()
            if ("ERROR" in line.upper() or "could not be loaded" in line)
            and "media_export" not in line and "librospack" not in line
            and "glsl120/indexed_8bit_image" not in line]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stop(proc):
    """Stop a process group we started (by its id)."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=10)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait(timeout=10)


def wait_master(uri, timeout=20.0):
    import xmlrpc.client
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        try:
            xmlrpc.client.ServerProxy(uri).getSystemState("/test")
            return True
        except OSError:
            time.sleep(0.2)
    return False


def test_committed_config_is_generated():
    out = subprocess.run([sys.executable, GENERATOR, "--robots", "8", "--enabled", "4",
                          "--map", "grid"], capture_output=True, text=True, check=True).stdout
    with open(CONFIG, encoding="utf-8") as f:
        assert f.read() == out, ("src/patrolling_sim/launch/patrol.rviz is stale: regenerate it "
                                 "(see its header)")
    for needle in ("Fixed Frame: map", "Topic: /map", "Marker Topic: /patrol_graph_markers",
                   "Topic: /robot_7/move_base/plan", "Topic: /robot_0/amcl_pose",
                   "Topic: /robot_3/base_scan", "Topic: /robot_5/particlecloud"):
        assert needle in out, needle


def test_rviz_loads_config_and_shows_map(tmp_path):
    for tool in ("xvfb-run", "xwd", "convert"):
        assert shutil.which(tool), f"{tool} missing (see scripts/packages.txt)"
    import cv2
    port = free_port()
    env = dict(os.environ)
    env["PATH"] = "/usr/bin:/bin:" + env.get("PATH", "")
    env["ROS_MASTER_URI"] = f"http://127.0.0.1:{port}"
    env["ROS_HOME"] = str(tmp_path / "ros")
    env.pop("ROS_IP", None)
    env["ROS_HOSTNAME"] = "127.0.0.1"
    master = subprocess.Popen(["roscore", "-p", str(port)], env=env, start_new_session=True,
                              stdout=open(tmp_path / "roscore.log", "w"),
                              stderr=subprocess.STDOUT)
    pub = None
    try:
        assert wait_master(env["ROS_MASTER_URI"]), "roscore did not come up"
        script = tmp_path / "pub.py"
        script.write_text(PUBLISHER)
        pub = subprocess.Popen(["/usr/bin/python3", str(script), SRC], env=env,
                               start_new_session=True,
                               stdout=open(tmp_path / "pub.log", "w"), stderr=subprocess.STDOUT)
        shot, log = tmp_path / "shot.xwd", tmp_path / "rviz.log"
        subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", "bash", "-c", SHOOT,
                        "shoot", CONFIG, str(log), str(shot), "10"], env=env, timeout=90,
                       check=True, start_new_session=True)
        assert pub.poll() is None, (tmp_path / "pub.log").read_text()
    finally:
        if pub is not None:
            stop(pub)
        stop(master)
    text = log.read_text()
    assert "rviz version" in text, text
    assert not rviz_errors(text), "\n".join(rviz_errors(text))
    png = tmp_path / "shot.png"
    subprocess.run(["convert", f"xwd:{shot}", str(png)], check=True)
    img = cv2.imread(str(png))
    assert img is not None and img.shape[:2] == (800, 1280)
    assert img.std() > 20, "screenshot is blank"
    # render area (between the Displays dock and the right edge, below the toolbar)
    render = img[120:680, 420:1220]
    light = (render.min(axis=2) > 180).mean()
    red = ((render[:, :, 2] > 150) & (render[:, :, 1] < 90) & (render[:, :, 0] < 90)).mean()
    cv2.imwrite(str(tmp_path / "render.png"), render)
    assert light > 0.2, f"map not visible in the 3D view ({light:.1%} light pixels)"
    assert red > 0.002, f"graph markers not visible ({red:.2%} red pixels)"


SHOOT_RUN = r'''
shot="$1"; delay="$2"; shift 2
"$@" > "$shot.runner.log" 2>&1 &
RUN=$!
sleep "$delay"
xwd -root -silent > "$shot"
wait $RUN
'''


def test_rviz_during_a_one_robot_experiment(tmp_path):
    """start_experiments.py --rviz on a virtual screen: rviz opens the run's own config
    while the experiment runs, logs no error, and shows the map, the graph and the robot;
    the run still ends normally with complete files."""
    import cv2
    from rosenv import ros_env
    env = dict(ros_env())
    shot = tmp_path / "run.xwd"
    start = os.path.join(ROOT, "scripts", "start_experiments.py")
    r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", "bash", "-c",
                        SHOOT_RUN, "shoot", str(shot), "22", "/usr/bin/python3", start,
                        "--map", "grid", "--robots", "1", "--alg", "CR", "--loc",
                        "fake_localization", "--timeout", "50", "--speedup", "2", "--rviz",
                        "--results-dir", str(tmp_path / "res")],
                       env=env, timeout=400, start_new_session=True)
    out = (tmp_path / "run.xwd.runner.log").read_text()
    assert r.returncode == 0, out[-3000:]
    prefix = next(p[:-len("_info.csv")] for p in glob_all(tmp_path / "res", "*_info.csv"))
    assert os.path.isfile(prefix + "_patrol.rviz")
    logs = glob_all(prefix + "_logs", "rviz*.log")
    assert logs, os.listdir(prefix + "_logs")
    text = "\n".join(open(p, errors="replace").read() for p in logs)
    assert not rviz_errors(text), "\n".join(rviz_errors(text))
    png = tmp_path / "run.png"
    subprocess.run(["convert", f"xwd:{shot}", str(png)], check=True)
    img = cv2.imread(str(png))
    assert img is not None and img.std() > 20, "screenshot is blank"
    render = img[120:680, 420:1220]
    light = (render.min(axis=2) > 180).mean()
    assert light > 0.1, f"map not visible in the 3D view ({light:.1%} light pixels)"


def glob_all(folder, pattern):
    import glob
    return sorted(glob.glob(os.path.join(str(folder), "**", pattern), recursive=True))
