"""Robot failures (attrition) as a reproducible scenario setting (see ``docs/scenarios.md``).

A *schedule* lists when which robot fails and, optionally, when it comes back. It is pure
data, computed once before a run from the ``--attrition`` option (or the ``attrition``
configuration key) and the run's seed, so graph mode and ROS mode fail the same robots at the
same sim times::

    2@600,5@1200          robot 2 fails 600 s after GO, robot 5 at 1200 s, for good
    2@600+300             robot 2 fails at 600 s and is back 300 s later
    random:rate=0.5,min_team=2[,repair=600]
                          every robot fails at random, 0.5 times per robot-hour (exponential
                          times), never leaving fewer than min_team robots working; with repair,
                          a failed robot is back after that many seconds (and may fail again)

A failed robot stops moving and stops communicating; what that means for each driver is the
driver's business (graph mode drops its events, the runner stops its agent and navigation).
"""
import math
import random
import re
from dataclasses import dataclass
from typing import List, Optional

from patrolling_sim.common.errors import PatrolInputError

_ITEM = re.compile(r"^\s*(\d+)\s*@\s*([0-9.]+)\s*(?:\+\s*([0-9.]+))?\s*$")


@dataclass(frozen=True)
class Failure:
    """Robot ``robot`` fails at ``t`` (s after GO); back at ``t + repair`` if repair is set."""
    robot: int
    t: float
    repair: Optional[float] = None

    @property
    def back(self) -> Optional[float]:
        return None if self.repair is None else self.t + self.repair


def parse_attrition(spec: Optional[str], team_size: int, duration: float = math.inf,
                    seed: int = 0, what: str = "--attrition") -> List[Failure]:
    """The schedule of ``spec`` (module docstring) for a team of ``team_size``, sorted by time.

    ``duration`` bounds the random model (sim seconds after GO).

    Raises:
        PatrolInputError: one line naming ``what`` and the wrong part.
    """
    spec = (spec or "").strip()
    if not spec or spec == "none":
        return []
    if spec.startswith("random"):
        _, _, args = spec.partition(":")
        kw = {}
        for item in filter(None, (a.strip() for a in args.split(","))):
            k, eq, v = item.partition("=")
            k = k.strip()
            if not eq or k not in ("rate", "min_team", "repair"):
                raise PatrolInputError(f"{what}: random takes rate=..., min_team=..., "
                                       f"repair=..., got '{item}'")
            try:
                kw[k] = float(v)
            except ValueError:
                raise PatrolInputError(f"{what}: random: {k} must be a number, got '{v}'")
        if "rate" not in kw or kw["rate"] <= 0:
            raise PatrolInputError(f"{what}: random: rate (failures per robot-hour) must be "
                                   "given and > 0")
        min_team = kw.get("min_team", 1)
        if min_team != int(min_team) or not 0 <= min_team <= team_size:
            raise PatrolInputError(f"{what}: random: min_team must be an integer in "
                                   f"[0, {team_size}], got {min_team:g}")
        repair = kw.get("repair")
        if repair is not None and repair <= 0:
            raise PatrolInputError(f"{what}: random: repair must be > 0 s, got {repair:g}")
        if not math.isfinite(duration):
            raise PatrolInputError(f"{what}: the random model needs a run duration (timeout)")
        return random_schedule(kw["rate"], team_size, duration, int(min_team), repair, seed)
    out = []
    for item in spec.split(","):
        m = _ITEM.match(item)
        if not m:
            raise PatrolInputError(f"{what}: expected ROBOT@SECONDS[+REPAIR] items separated by "
                                   f"commas, or random:rate=...; got '{item.strip()}'")
        robot, t = int(m.group(1)), float(m.group(2))
        repair = float(m.group(3)) if m.group(3) else None
        if robot >= team_size:
            raise PatrolInputError(f"{what}: robot {robot} is not in a team of {team_size} "
                                   f"(ids 0..{team_size - 1})")
        if repair is not None and repair <= 0:
            raise PatrolInputError(f"{what}: robot {robot}: repair time must be > 0 s")
        out.append(Failure(robot, t, repair))
    out.sort(key=lambda f: (f.t, f.robot))
    for a in out:                       # a robot cannot fail again while it is down
        for b in out:
            if b is not a and b.robot == a.robot and a.t <= b.t and (a.back is None or
                                                                     b.t < a.back):
                raise PatrolInputError(f"{what}: robot {a.robot} fails at {b.t:g} s while "
                                       f"already failed since {a.t:g} s")
    if len({f.robot for f in out if f.repair is None}) >= team_size:
        raise PatrolInputError(f"{what}: every robot of the team would be gone for good")
    return out


def random_schedule(rate_per_hour: float, team_size: int, duration: float, min_team: int = 1,
                    repair: Optional[float] = None, seed: int = 0) -> List[Failure]:
    """Exponential failure times per working robot (``rate_per_hour``), seeded; a failure
    that would leave fewer than ``min_team`` robots working is skipped (that robot draws its
    next time)."""
    rng = random.Random(seed * 104729 + 17)
    lam = rate_per_hour / 3600.0
    nxt = {r: rng.expovariate(lam) for r in range(team_size)}
    down_until = {}
    out = []
    while True:
        r = min(nxt, key=lambda k: (nxt[k], k))
        t = nxt[r]
        if t > duration:
            break
        working = sum(1 for k in range(team_size) if down_until.get(k, -1.0) <= t)
        if working - 1 >= min_team:
            out.append(Failure(r, t, repair))
            if repair is None:
                down_until[r] = math.inf
                del nxt[r]
                if not nxt:
                    break
                continue
            down_until[r] = t + repair
            nxt[r] = t + repair + rng.expovariate(lam)
        else:
            nxt[r] = t + rng.expovariate(lam)
    return out


def describe(schedule: List[Failure]) -> str:
    """The schedule in the explicit ``ROBOT@T[+REPAIR]`` form (recorded with the results)."""
    return ",".join(f"{f.robot}@{f.t:g}" + (f"+{f.repair:g}" if f.repair is not None else "")
                    for f in schedule) or "none"
