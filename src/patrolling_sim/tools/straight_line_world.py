"""The abstract world's motion model, free of ROS (docs/abstract_world.md): points moving
in straight lines at one speed, time counted in whole steps. Used by abstract_world.py."""
import math

EPS = 1e-9


class StraightLineWorld:
    """The motion model, free of ROS: points moving in straight lines at one speed, time in
    whole steps (so ``time`` is exact and the same on every machine)."""

    def __init__(self, positions, speed, step):
        if not speed > 0:
            raise ValueError(f"~speed must be > 0, got {speed}")
        if not step > 0:
            raise ValueError(f"~step must be > 0, got {step}")
        self.speed = float(speed)
        self.step_length = float(step)
        self.pos = [[float(x), float(y)] for x, y in positions]
        self.yaw = [math.pi / 2] * len(self.pos)
        self.goal = [None] * len(self.pos)
        self.start = [0.0] * len(self.pos)     # sim time before which a robot stays put
        self.steps = 0

    @property
    def time(self):
        return self.steps * self.step_length

    def set_goal(self, i, x, y, start=0.0):
        """Robot ``i`` heads for (x, y) from where it is now, from the next step on, or if
        later from the first step that begins at or after sim time ``start``."""
        self.goal[i] = (float(x), float(y))
        self.start[i] = float(start)

    def stop(self, i):
        """Robot ``i`` stays where it is."""
        self.goal[i] = None

    def moving(self, i):
        return self.goal[i] is not None

    def advance(self):
        """One step of motion; returns the robots that reached their goal in this step
        (they stop there)."""
        began = self.time
        self.steps += 1
        reach = self.speed * self.step_length
        arrived = []
        for i, g in enumerate(self.goal):
            if g is None or self.start[i] > began + EPS:
                continue
            p = self.pos[i]
            dx, dy = g[0] - p[0], g[1] - p[1]
            d = math.hypot(dx, dy)
            if d > EPS:
                self.yaw[i] = math.atan2(dy, dx)
            if d <= reach + EPS:
                p[0], p[1] = g
                self.goal[i] = None
                arrived.append(i)
            else:
                p[0] += dx / d * reach
                p[1] += dy / d * reach
        return arrived


def read_positions(flat, team_size):
    """[(x, y)] of the first ``team_size`` robots of ``/initial_pos`` (ValueError, one line)."""
    if flat is None:
        raise ValueError("/initial_pos is not set")
    try:
        flat = [float(v) for v in flat]
    except (TypeError, ValueError):
        raise ValueError(f"/initial_pos must be a flat list of numbers, got {flat!r}") from None
    n = len(flat) // 2 if team_size is None else int(team_size)
    if n < 1 or len(flat) < 2 * n:
        raise ValueError(f"~team_size {n} does not fit /initial_pos ({len(flat) // 2} "
                         "positions)")
    return [(flat[2 * i], flat[2 * i + 1]) for i in range(n)]
