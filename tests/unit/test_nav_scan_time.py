"""move_base places a laser scan in the map with the robot's pose at the scan's stamp, not
with the pose of the control cycle that reads it (docs/navigation.md, "Scans at their own
time"). Driven without a ROS master: the MoveBase glue with a map, odometry and one scan."""
import math
import threading

import numpy as np
import pytest

rospy = pytest.importorskip("rospy", reason="rospy (Debian: python3-rospy) missing")
from sensor_msgs.msg import LaserScan  # noqa: E402

from spqrel_nav_lite.mapio import OccupancyMap  # noqa: E402
from spqrel_nav_lite.geometry import PoseHistory  # noqa: E402
from spqrel_nav_lite.move_base_node import MoveBase  # noqa: E402
from spqrel_nav_lite.obstacles import ObstacleMemory, scan_points, to_world  # noqa: E402
from spqrel_nav_lite.particle_filter import LikelihoodField  # noqa: E402

from nav_common import fake_scan  # noqa: E402

RES = 0.05
LASER_X = 0.15


@pytest.fixture(autouse=True)
def ros_time():
    """rospy.get_time() without a node: wall time."""
    rospy.rostime.set_rostime_initialized(True)
    yield


def corridor():
    """A 10 m corridor, 1.6 m wide (walls 0.1 m thick at y 0-0.1 and 1.7-1.8)."""
    d = np.zeros((int(1.8 / RES), int(10.0 / RES)), dtype=np.int8)
    d[:2, :] = d[-2:, :] = 100
    d[:, :2] = d[:, -2:] = 100
    return OccupancyMap(d, RES)


def scan_from(m, pose, stamp):
    """A 181-beam scan (-90 to +90 degrees) taken at ``stamp`` from map pose ``pose``."""
    angle_min, inc = -math.pi / 2, math.radians(1.0)
    scan = LaserScan(angle_min=angle_min, angle_increment=inc, range_min=0.05, range_max=20.0,
                     ranges=fake_scan(m, pose, angle_min + inc * np.arange(181), LASER_X))
    scan.header.stamp = rospy.Time.from_sec(stamp)
    return scan


def glue(m, odom, loc):
    mb = MoveBase.__new__(MoveBase)       # the glue only: no node, no planner
    mb.lock = threading.Lock()
    mb.odom = PoseHistory(horizon=10.0)
    for stamp, pose in odom:
        mb.odom.add(stamp, pose)
    mb.loc = loc
    mb.laser_x = LASER_X
    mb.obstacle_range = 2.5
    mb.unexplained_dist = 0.25
    mb.field = LikelihoodField(m, max_dist=1.0)
    mb.memory = ObstacleMemory(cell=0.1, timeout=3.0)
    return mb


@pytest.mark.parametrize("turn", [0.1, 0.3])
def test_a_scan_of_the_step_before_is_placed_where_it_was_taken(turn):
    """The robot turns in place in a corridor; the control cycle at 10.1 s reads the scan
    taken at 10.0 s. Its walls must stay walls: no temporary obstacle, and the points the
    controller gets (robot frame, now) lie on the walls."""
    m = corridor()
    then = (5.0, 0.9, -0.2)                 # map pose when the scan was taken
    odom = [(9.9, (1.0, 2.0, 0.3)), (10.0, (1.0, 2.0, 0.3)), (10.1, (1.0, 2.0, 0.3 + turn))]
    mb = glue(m, odom, (then, (1.0, 2.0, 0.3), 10.0))    # localised at 10.0 s
    mb.scan = scan = scan_from(m, then, 10.0)
    now = mb.pose()
    assert now == pytest.approx((5.0, 0.9, -0.2 + turn))

    # the set-up can tell: placed with the pose of now, this scan's walls leave the walls
    pts, r, _ = scan_points(scan.ranges, scan.angle_min, scan.angle_increment, 0.05, 20.0,
                            LASER_X, 1, 2.5)
    wrong = to_world(pts, now)
    assert (mb.field.lookup(wrong[:, 0], wrong[:, 1]) > 0.25).sum() >= (1 if turn < 0.2 else 5)

    near, unexplained = MoveBase.laser(mb, now)
    assert len(unexplained) == 0 and len(mb.memory) == 0
    seen = to_world(near, now)              # the controller's points, back in the map
    assert len(seen) > 50
    assert mb.field.lookup(seen[:, 0], seen[:, 1]).max() <= 2 * RES


def test_a_robot_ahead_is_placed_where_the_scan_saw_it():
    """An unmapped obstacle (another robot) seen in the scan of the step before, while the
    robot drove 0.05 m and turned 0.1 rad: the controller gets it where it is from the
    robot's pose now, and the memory holds it at its place in the map."""
    m = corridor()
    d = m.data.copy()
    d[int(0.8 / RES):int(1.0 / RES), int(6.4 / RES):int(6.6 / RES)] = 100    # 0.2 m box
    with_box = OccupancyMap(d, RES)
    then = (5.0, 0.9, 0.0)
    odom = [(10.0, (0.0, 0.0, 0.0)), (10.1, (0.05, 0.0, 0.1))]
    mb = glue(m, odom, (then, (0.0, 0.0, 0.0), 10.0))        # the map without the box
    mb.scan = scan_from(with_box, then, 10.0)
    now = mb.pose()
    near, unexplained = MoveBase.laser(mb, now)
    assert len(unexplained) > 0

    def inside(p, margin):                  # the box spans x 6.4-6.6, y 0.8-1.0
        return np.all((p[:, 0] > 6.4 - margin) & (p[:, 0] < 6.6 + margin) &
                      (p[:, 1] > 0.8 - margin) & (p[:, 1] < 1.0 + margin))
    assert inside(to_world(unexplained, now), 0.05)
    cells = mb.memory.points()
    assert len(cells) > 0 and inside(cells, 0.1)
