"""Communication models: which inter-robot messages arrive, and when (``docs/scenarios.md``).

A model decides, for one message from robot ``s`` to robot ``r`` sent at time ``t``, whether
it is delivered and after what delay. It is a pure, seeded component: both drivers (graph
mode and the ROS agent) ask the same object, so a scenario behaves the same in both modes.
Decisions are made per *link* (sender, receiver): a broadcast to N-1 teammates is N-1
decisions, so with loss some teammates hear a message and others do not.

Models (the ``--comm`` option / ``comm`` configuration key, see :func:`parse_comm`)::

    perfect                                     everything arrives
    bernoulli:p=0.1                             each link loses a message with probability p
    ge:p_good=0.0,p_bad=0.8,to_bad=0.05,to_good=0.5
                                                Gilbert-Elliott bursty loss: every link is a
                                                two-state Markov chain in continuous time
                                                (rates to_bad, to_good per second); a message
                                                is lost with p_good or p_bad by the state
    range:r=10,los=true                         delivered only within r metres and, with los,
                                                if the straight line crosses no occupied cell
    ...;delay=const:0.5 | uniform:0.1,0.6 | exp:0.3 | normal:0.5,0.1
                                                delay distribution (s) of delivered messages
                                                (normal is truncated at 0); default none

Every model keeps counters (``sent`` link attempts, ``delivered``, ``lost``) for the run's
metrics.
"""
import math
import random
from dataclasses import dataclass, field
from typing import Callable, Dict, Optional, Tuple

from patrolling_sim.common.errors import PatrolInputError
import numpy as np

Position = Tuple[float, float]


# ------------------------------------------------------------------------------ delays
@dataclass
class Delay:
    """A delay distribution (s): ``kind`` const | uniform | exp | normal."""
    kind: str = "none"
    a: float = 0.0
    b: float = 0.0

    def sample(self, rng: random.Random) -> float:
        if self.kind == "none":
            return 0.0
        if self.kind == "const":
            return self.a
        if self.kind == "uniform":
            return rng.uniform(self.a, self.b)
        if self.kind == "exp":
            return rng.expovariate(1.0 / self.a) if self.a > 0 else 0.0
        if self.kind == "normal":
            return max(0.0, rng.gauss(self.a, self.b))
        raise ValueError(self.kind)

    @property
    def mean(self) -> float:
        """Mean delay (for ``normal``, of the untruncated distribution)."""
        return {"none": 0.0, "const": self.a, "uniform": (self.a + self.b) / 2,
                "exp": self.a, "normal": self.a}[self.kind]


# ------------------------------------------------------------------------------ models
@dataclass
class CommModel:
    """Base: perfect links. Subclasses override :meth:`_lost`."""
    delay: Delay = field(default_factory=Delay)
    seed: int = 0
    sent: int = 0
    delivered: int = 0
    lost: int = 0

    def __post_init__(self):
        self.rng = random.Random(self.seed)

    name = "perfect"

    def link(self, sender: int, receiver: int, t: float,
             positions: Optional[Callable[[int], Optional[Position]]] = None
             ) -> Optional[float]:
        """Delay (s) of the message sender -> receiver sent at ``t``, or None if it is lost.

        ``positions(robot)`` gives a robot's (x, y) in metres at ``t`` (needed by the range
        model; others ignore it)."""
        self.sent += 1
        if self._lost(sender, receiver, t, positions):
            self.lost += 1
            return None
        self.delivered += 1
        return self.delay.sample(self.rng)

    def _lost(self, sender, receiver, t, positions) -> bool:
        return False

    def counters(self) -> Dict[str, int]:
        return {"sent": self.sent, "delivered": self.delivered, "lost": self.lost}

    def params(self) -> str:
        """The model's parameters as in its specification (``:k=v,...``)."""
        return ""

    def describe(self) -> str:
        """The specification :func:`parse_comm` reads back into an equal model."""
        d = self.delay
        delay = "" if d.kind == "none" else (
            f";delay={d.kind}:{d.a:g}" + (f",{d.b:g}" if _DELAYS[d.kind] == 2 else ""))
        return self.name + self.params() + delay


@dataclass
class Bernoulli(CommModel):
    """Each link loses each message independently with probability ``p``."""
    p: float = 0.0
    name = "bernoulli"

    def _lost(self, sender, receiver, t, positions):
        return self.p > 0 and self.rng.random() < self.p

    def params(self):
        return f":p={self.p:g}"


@dataclass
class GilbertElliott(CommModel):
    """Bursty loss (Gilbert 1960, Elliott 1963) in continuous time, one chain per link.

    A link is *good* or *bad*; it goes bad at rate ``to_bad`` and recovers at rate
    ``to_good`` (per second), so a bad period lasts 1/to_good s on average and the link is bad
    a share ``to_bad / (to_bad + to_good)`` of the time. A message is lost with probability
    ``p_good`` or ``p_bad`` by the link's state at the send time. Links start in the
    stationary distribution."""
    p_good: float = 0.0
    p_bad: float = 1.0
    to_bad: float = 0.05
    to_good: float = 0.5
    name = "ge"

    def __post_init__(self):
        super().__post_init__()
        self._state: Dict[Tuple[int, int], Tuple[bool, float]] = {}   # link -> (bad, t)

    @property
    def bad_share(self) -> float:
        return self.to_bad / (self.to_bad + self.to_good)

    @property
    def loss_rate(self) -> float:
        """Long-run share of lost messages (messages sent independently of the state)."""
        return self.bad_share * self.p_bad + (1 - self.bad_share) * self.p_good

    def bad_at(self, link: Tuple[int, int], t: float) -> bool:
        """The link's state at ``t`` (advanced exactly from its state at the last query)."""
        if link not in self._state:
            bad = self.rng.random() < self.bad_share
        else:
            was_bad, t0 = self._state[link]
            dt = max(0.0, t - t0)
            # two-state chain: P(bad at t0+dt | state at t0) relaxes to bad_share at rate
            # to_bad + to_good
            relax = math.exp(-(self.to_bad + self.to_good) * dt)
            p_bad = self.bad_share + ((1.0 if was_bad else 0.0) - self.bad_share) * relax
            bad = self.rng.random() < p_bad
        self._state[link] = (bad, t)
        return bad

    def _lost(self, sender, receiver, t, positions):
        bad = self.bad_at((sender, receiver), t)
        return self.rng.random() < (self.p_bad if bad else self.p_good)

    def params(self):
        return (f":p_good={self.p_good:g},p_bad={self.p_bad:g},to_bad={self.to_bad:g},"
                f"to_good={self.to_good:g}")


@dataclass
class RangeLOS(CommModel):
    """Delivered only if the robots are within ``r`` m and, with ``los``, the straight line
    between them crosses no occupied cell of ``occupancy`` (an
    :class:`~spqrel_nav_lite.mapio.OccupancyMap`). Unknown positions: lost."""
    r: float = 10.0
    los: bool = True
    occupancy: object = None
    name = "range"

    def _lost(self, sender, receiver, t, positions):
        if positions is None:
            raise ValueError("the range model needs the robots' positions")
        a, b = positions(sender), positions(receiver)
        if a is None or b is None:
            return True
        if math.hypot(a[0] - b[0], a[1] - b[1]) > self.r:
            return True
        return bool(self.los and self.occupancy is not None and
                    not line_of_sight(self.occupancy, a, b))

    def params(self):
        return f":r={self.r:g},los={'true' if self.los else 'false'}"


#: id(map) -> (map, rows of bytes: 1 where occupied): a Python bytes lookup per cell is an
#: order of magnitude faster than indexing the numpy array one element at a time
_BLOCKED: Dict[int, tuple] = {}


def _blocked_rows(occ):
    hit = _BLOCKED.get(id(occ))
    if hit is None or hit[0] is not occ:
        rows = [bytes(r) for r in (np.asarray(occ.data) == 100).astype(np.uint8)]
        if len(_BLOCKED) > 8:
            _BLOCKED.clear()
        hit = _BLOCKED[id(occ)] = (occ, rows)
    return hit[1]


def line_of_sight(occ, a: Position, b: Position) -> bool:
    """True if the segment a-b (metres) crosses no occupied cell of ``occ``: every cell the
    segment passes through is checked (a grid traversal after Amanatides & Woo 1987, exact for
    segments, unlike sampling). Cells outside the map block the line."""
    res = occ.resolution
    x0 = (a[0] - occ.origin[0]) / res
    y0 = (a[1] - occ.origin[1]) / res
    x1 = (b[0] - occ.origin[0]) / res
    y1 = (b[1] - occ.origin[1]) / res
    i, j = int(math.floor(x0)), int(math.floor(y0))
    i1, j1 = int(math.floor(x1)), int(math.floor(y1))
    dx, dy = x1 - x0, y1 - y0
    si = 1 if dx > 0 else -1
    sj = 1 if dy > 0 else -1
    tdx = abs(1.0 / dx) if dx else math.inf
    tdy = abs(1.0 / dy) if dy else math.inf
    tmx = ((i + 1 - x0) if dx > 0 else (x0 - i)) * tdx if dx else math.inf
    tmy = ((j + 1 - y0) if dy > 0 else (y0 - j)) * tdy if dy else math.inf
    rows, w, h = _blocked_rows(occ), occ.width, occ.height
    for _ in range(abs(i1 - i) + abs(j1 - j) + 1):
        if not (0 <= i < w and 0 <= j < h) or rows[j][i]:
            return False
        if i == i1 and j == j1:
            break
        if tmx < tmy:
            tmx += tdx
            i += si
        else:
            tmy += tdy
            j += sj
    return True


# ------------------------------------------------------------------------------ parsing
_MODELS = {"perfect": (CommModel, {}),
           "none": (CommModel, {}),
           "bernoulli": (Bernoulli, {"p": float}),
           "ge": (GilbertElliott, {"p_good": float, "p_bad": float, "to_bad": float,
                                   "to_good": float}),
           "range": (RangeLOS, {"r": float, "los": bool})}
_DELAYS = {"const": 1, "uniform": 2, "exp": 1, "normal": 2}


def _bool(text):
    t = text.strip().lower()
    if t in ("1", "true", "yes", "on"):
        return True
    if t in ("0", "false", "no", "off"):
        return False
    raise ValueError


def parse_comm(spec: str, seed: int = 0, occupancy=None, what: str = "--comm") -> CommModel:
    """A model from ``MODEL[:k=v,...][;delay=KIND:a[,b]]`` (module docstring).

    Raises:
        PatrolInputError: one line naming ``what`` and the part that is wrong.
    """
    spec = (spec or "perfect").strip()
    parts = [p.strip() for p in spec.split(";") if p.strip()]
    head, rest = parts[0], parts[1:]
    name, _, args = head.partition(":")
    name = name.strip().lower()
    if name not in _MODELS:
        raise PatrolInputError(f"{what}: unknown communication model '{name}' (known: "
                               f"{', '.join(k for k in _MODELS if k != 'none')})")
    cls, types = _MODELS[name]
    kw = {}
    for item in filter(None, (a.strip() for a in args.split(","))):
        k, eq, v = item.partition("=")
        k = k.strip()
        if not eq or k not in types:
            raise PatrolInputError(f"{what}: model '{name}' takes " +
                                   (", ".join(f"{t}=..." for t in types) or "no parameter") +
                                   f", got '{item}'")
        try:
            kw[k] = _bool(v) if types[k] is bool else float(v)
        except ValueError:
            raise PatrolInputError(f"{what}: {name}: {k} must be "
                                   f"{'true or false' if types[k] is bool else 'a number'}, "
                                   f"got '{v.strip()}'")
    for k, v in kw.items():
        if k.startswith("p") and not 0.0 <= v <= 1.0:
            raise PatrolInputError(f"{what}: {name}: {k} must be in [0, 1], got {v:g}")
        if k in ("to_bad", "to_good") and v <= 0:
            raise PatrolInputError(f"{what}: {name}: {k} must be > 0 (per second), got {v:g}")
        if k == "r" and v <= 0:
            raise PatrolInputError(f"{what}: range: r must be > 0 m, got {v:g}")
    delay = Delay()
    for p in rest:
        k, eq, v = p.partition("=")
        if k.strip() != "delay" or not eq:
            raise PatrolInputError(f"{what}: expected ';delay=KIND:a[,b]' after the model, "
                                   f"got '{p}'")
        kind, _, nums = v.strip().partition(":")
        kind = kind.strip().lower()
        if kind not in _DELAYS:
            raise PatrolInputError(f"{what}: unknown delay distribution '{kind}' (known: "
                                   f"{', '.join(_DELAYS)})")
        try:
            vals = [float(x) for x in nums.split(",") if x.strip()]
        except ValueError:
            raise PatrolInputError(f"{what}: delay {kind}: parameters must be numbers, "
                                   f"got '{nums}'")
        if len(vals) != _DELAYS[kind] or any(x < 0 for x in vals):
            raise PatrolInputError(f"{what}: delay {kind} takes {_DELAYS[kind]} parameter(s) "
                                   f">= 0, got '{nums}'")
        if kind == "uniform" and vals[1] < vals[0]:
            raise PatrolInputError(f"{what}: delay uniform: high < low ('{nums}')")
        delay = Delay(kind, vals[0], vals[1] if len(vals) > 1 else 0.0)
    if name == "range":
        kw["occupancy"] = occupancy
    return cls(delay=delay, seed=seed, **kw)
