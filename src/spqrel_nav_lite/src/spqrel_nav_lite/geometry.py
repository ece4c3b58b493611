"""2-D rigid transforms as (x, y, yaw) tuples, and quaternion helpers. No ROS imports."""
import bisect
import math


def normalize_angle(a):
    """Angle wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def compose(a, b):
    """a o b: the pose b expressed in a's parent frame."""
    ax, ay, at = a
    bx, by, bt = b
    c, s = math.cos(at), math.sin(at)
    return (ax + c * bx - s * by, ay + s * bx + c * by, normalize_angle(at + bt))


def inverse(a):
    ax, ay, at = a
    c, s = math.cos(at), math.sin(at)
    return (-c * ax - s * ay, s * ax - c * ay, normalize_angle(-at))


def relative(a, b):
    """a^-1 o b: pose b seen from pose a."""
    return compose(inverse(a), b)


def yaw_from_quaternion(x, y, z, w):
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw):
    """(x, y, z, w) of a rotation about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


class PoseHistory:
    """A short, time-ordered history of (stamp_s, pose) for looking up the pose closest to a
    stamp (e.g. odometry at the time of a localiser update)."""

    def __init__(self, horizon=5.0):
        self.horizon = float(horizon)
        self.stamps = []
        self.poses = []

    def add(self, stamp, pose):
        if self.stamps and stamp < self.stamps[-1]:     # time went backwards: restart
            self.stamps, self.poses = [], []
        self.stamps.append(stamp)
        self.poses.append(pose)
        cut = bisect.bisect_left(self.stamps, stamp - self.horizon)
        if cut > 0:
            del self.stamps[:cut]
            del self.poses[:cut]

    def latest(self):
        return (self.stamps[-1], self.poses[-1]) if self.stamps else None

    def at(self, stamp):
        """Pose at ``stamp`` (the stored pose itself at a stored stamp, else linear
        interpolation between neighbours, clamped at the ends), or None if empty. Exact at a
        stored stamp, so a lookup at the latest odometry's stamp gives the very pose
        ``latest()`` gives (interpolating with weight 1 differed in the last bits in about a
        third of the cases), and move_base's scan of the current step needs no transform."""
        if not self.stamps:
            return None
        k = bisect.bisect_left(self.stamps, stamp)
        if k >= len(self.stamps):
            return self.poses[-1]
        if k <= 0 or self.stamps[k] == stamp:
            return self.poses[k]
        t0, t1 = self.stamps[k - 1], self.stamps[k]
        p0, p1 = self.poses[k - 1], self.poses[k]
        f = 0.0 if t1 <= t0 else (stamp - t0) / (t1 - t0)
        return (p0[0] + f * (p1[0] - p0[0]), p0[1] + f * (p1[1] - p0[1]),
                normalize_angle(p0[2] + f * normalize_angle(p1[2] - p0[2])))
