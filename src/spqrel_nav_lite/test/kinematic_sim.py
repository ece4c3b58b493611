#!/usr/bin/python3
"""Small kinematic multi-robot simulator for the spqrel_nav_lite rostests.

Unicycle robots (radius 0.225) integrate robot_i/cmd_vel (0.2 s watchdog); each publishes
robot_i/odom (biased odometry, like Stage's odom_error), robot_i/base_pose_ground_truth (frame
map) and robot_i/base_scan (270.25 deg, ray-cast over the map with numpy, other robots and
static circular obstacles included); /clock runs at ~speedup x wall time. Moves that would
touch a wall, a robot or an obstacle are refused and counted on /contacts (std_msgs/Int32).

Params: ~map (yaml), ~poses "x y yaw ...", ~obstacles "x y r ...", ~speedup (1), ~rate (20),
~scan_rate (10), ~beams (1081), ~range_max (20), ~odom_error "ex ey eth" (0.01 0.01 0.05),
~seed (0).
"""
import math
import sys
import time

import numpy as np
import rospy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Int32

from spqrel_nav_lite.mapio import FREE, load_map
from spqrel_nav_lite.geometry import quaternion_from_yaw

RADIUS = 0.225
LASER_X = 0.15


def floats(text, name, group):
    try:
        v = [float(t) for t in str(text).split()]
    except ValueError:
        sys.exit(f"kinematic_sim: error: ~{name}: not a list of numbers: {text!r}")
    if len(v) % group:
        sys.exit(f"kinematic_sim: error: ~{name}: needs groups of {group} numbers")
    return [v[i:i + group] for i in range(0, len(v), group)]


class Sim:
    def __init__(self):
        self.map = load_map(rospy.get_param("~map"))
        self.poses = np.array(floats(rospy.get_param("~poses", "1 1 0"), "poses", 3))
        obst = floats(rospy.get_param("~obstacles", ""), "obstacles", 3)
        self.obstacles = np.array(obst).reshape(-1, 3)
        self.speedup = float(rospy.get_param("~speedup", 1.0))
        self.dt = 1.0 / float(rospy.get_param("~rate", 20.0))
        self.scan_every = max(1, int(round(float(rospy.get_param("~rate", 20.0))
                                           / float(rospy.get_param("~scan_rate", 10.0)))))
        self.beams = int(rospy.get_param("~beams", 1081))
        self.range_max = float(rospy.get_param("~range_max", 20.0))
        err = [float(t) for t in str(rospy.get_param("~odom_error", "0.01 0.01 0.05")).split()]
        rng = np.random.default_rng(int(rospy.get_param("~seed", 0)))
        n = len(self.poses)
        self.bias = np.column_stack([rng.uniform(-err[0], err[0], n),
                                     rng.uniform(-err[1], err[1], n),
                                     rng.uniform(-err[2], err[2], n)])
        self.odom = np.zeros((n, 3))
        self.cmd = np.zeros((n, 2))
        self.cmd_t = np.full(n, -1e9)
        self.vel = np.zeros((n, 2))
        self.t = 0.0
        self.contacts = 0
        self.fov = math.radians(270.25)
        self.angles = -self.fov / 2 + self.fov * np.arange(self.beams) / (self.beams - 1)
        self.clear = self.map.clearance
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=1)
        self.contact_pub = rospy.Publisher("/contacts", Int32, queue_size=1, latch=True)
        self.pubs = []
        for i in range(n):
            ns = f"robot_{i}"
            self.pubs.append((rospy.Publisher(f"{ns}/odom", Odometry, queue_size=5),
                              rospy.Publisher(f"{ns}/base_pose_ground_truth", Odometry,
                                              queue_size=5),
                              rospy.Publisher(f"{ns}/base_scan", LaserScan, queue_size=2)))
            rospy.Subscriber(f"{ns}/cmd_vel", Twist, self.on_cmd, callback_args=i, queue_size=1)
        self.contact_pub.publish(Int32(0))

    def on_cmd(self, msg, i):
        self.cmd[i] = (msg.linear.x, msg.angular.z)
        self.cmd_t[i] = self.t

    def collides(self, i, x, y):
        if self.map.clearance_at(x, y) < RADIUS * 0.9:
            return True
        for j, (px, py, _) in enumerate(self.poses):
            if j != i and math.hypot(px - x, py - y) < 2 * RADIUS:
                return True
        for ox, oy, r in self.obstacles:
            if math.hypot(ox - x, oy - y) < RADIUS + r:
                return True
        return False

    def step(self):
        for i in range(len(self.poses)):
            v, w = self.cmd[i] if self.t - self.cmd_t[i] <= 0.2 else (0.0, 0.0)
            x, y, th = self.poses[i]
            nth = th + w * self.dt
            nx = x + v * self.dt * math.cos(th + 0.5 * w * self.dt)
            ny = y + v * self.dt * math.sin(th + 0.5 * w * self.dt)
            if abs(v) > 1e-9 and self.collides(i, nx, ny):
                self.contacts += 1
                self.contact_pub.publish(Int32(self.contacts))
                v = 0.0
                nx, ny = x, y
            self.poses[i] = (nx, ny, math.atan2(math.sin(nth), math.cos(nth)))
            self.vel[i] = (v, w)
            # biased odometry
            ox, oy, oth = self.odom[i]
            vo, wo = v * (1 + self.bias[i, 0]), w * (1 + self.bias[i, 2])
            oth2 = oth + wo * self.dt
            self.odom[i] = (ox + vo * self.dt * math.cos(oth + 0.5 * wo * self.dt),
                            oy + vo * self.dt * math.sin(oth + 0.5 * wo * self.dt),
                            math.atan2(math.sin(oth2), math.cos(oth2)))
        self.t += self.dt

    def raycast(self, i):
        x, y, th = self.poses[i]
        sx, sy = x + LASER_X * math.cos(th), y + LASER_X * math.sin(th)
        a = th + self.angles
        dx, dy = np.cos(a), np.sin(a)
        m = self.map
        t = np.zeros(self.beams)
        done = np.zeros(self.beams, dtype=bool)
        for _ in range(200):
            px, py = sx + t * dx, sy + t * dy
            ci = np.floor((px - m.origin[0]) / m.resolution).astype(int)
            cj = np.floor((py - m.origin[1]) / m.resolution).astype(int)
            inside = (ci >= 0) & (ci < m.width) & (cj >= 0) & (cj < m.height)
            cic, cjc = np.clip(ci, 0, m.width - 1), np.clip(cj, 0, m.height - 1)
            hit = ~inside | (m.data[cjc, cic] != FREE)
            done |= hit | (t >= self.range_max)
            if done.all():
                break
            step = np.maximum(self.clear[cjc, cic], 0.5 * m.resolution)
            t = np.where(done, t, t + step)
        t = np.minimum(t, self.range_max)
        circles = [(px, py, RADIUS) for j, (px, py, _) in enumerate(self.poses) if j != i]
        circles += [tuple(o) for o in self.obstacles]
        for cx, cy, r in circles:
            fx, fy = sx - cx, sy - cy
            b = fx * dx + fy * dy
            c = fx * fx + fy * fy - r * r
            disc = b * b - c
            ok = disc >= 0
            root = -b - np.sqrt(np.where(ok, disc, 0.0))
            ok &= root > 0
            t = np.where(ok, np.minimum(t, root), t)
        t = np.where(t >= self.range_max, self.range_max, t)
        return t

    def publish(self, do_scan):
        stamp = rospy.Time.from_sec(self.t)
        self.clock_pub.publish(Clock(clock=stamp))
        for i, (odom_pub, gt_pub, scan_pub) in enumerate(self.pubs):
            ns = f"robot_{i}"
            for pub, pose, frame in ((odom_pub, self.odom[i], f"{ns}/odom"),
                                     (gt_pub, self.poses[i], "map")):
                msg = Odometry()
                msg.header.stamp = stamp
                msg.header.frame_id = frame
                msg.child_frame_id = f"{ns}/base_link"
                msg.pose.pose.position.x, msg.pose.pose.position.y = pose[0], pose[1]
                q = quaternion_from_yaw(pose[2])
                o = msg.pose.pose.orientation
                o.x, o.y, o.z, o.w = q
                msg.twist.twist.linear.x, msg.twist.twist.angular.z = self.vel[i]
                pub.publish(msg)
            if do_scan:
                scan = LaserScan()
                scan.header.stamp = stamp
                scan.header.frame_id = f"{ns}/base_laser_link"
                scan.angle_min, scan.angle_max = -self.fov / 2, self.fov / 2
                scan.angle_increment = self.fov / (self.beams - 1)
                scan.range_min, scan.range_max = 0.0, self.range_max
                scan.scan_time = self.dt * self.scan_every
                scan.ranges = self.raycast(i).tolist()
                scan_pub.publish(scan)

    def run(self):
        wall_dt = self.dt / self.speedup
        k = 0
        nxt = time.monotonic()
        while not rospy.is_shutdown():
            self.step()
            self.publish(k % self.scan_every == 0)
            k += 1
            nxt += wall_dt
            delay = nxt - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                nxt = time.monotonic()


if __name__ == "__main__":
    rospy.init_node("kinematic_sim")
    Sim().run()
