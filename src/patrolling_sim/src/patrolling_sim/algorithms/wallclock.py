"""The original's wall-clock draws, emulated, for measuring what they change.

The original's RAND, CR, HCR, HPCC, GBS and SEBS agents call ``srand(time(NULL))`` right
before the ``rand()`` that picks a random neighbour (RAND) or breaks a tie (the others), so
a draw depends only on the wall-clock second in which it is made: every robot deciding in
the same second, in its own process, gets the same number, and the faster the simulation
runs, the more decisions share a second. This project draws from each robot's seeded
generator instead (docs/fidelity.md, "Ties"). To measure the difference, a run can ask for
the original's draws with two strategy parameters (``params``, the same for every robot):

- ``original_draws_pace`` (float, default 0 = off): the pace (simulated seconds per wall
  second) the emulated original ran at; the wall-clock second of a draw made at simulated
  time ``t`` is ``epoch + floor(t / pace)``;
- ``original_draws_epoch`` (int, default 0): the wall-clock second at the clock's zero
  (vary it with the run to draw from other seconds).

A draw then picks ``seq[rand() % len(seq)]`` with glibc's ``rand()`` just after
``srand(second)`` (:class:`~patrolling_sim.planning.routes.CRand`): the original's own
number for that second. The draws are deterministic per run, like every other draw here.
"""
import math
from typing import Optional, Sequence

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.planning.routes import CRand

PACE_PARAM = "original_draws_pace"
EPOCH_PARAM = "original_draws_epoch"


class WallClockDraws:
    """``choice(seq)`` as the original's ``srand(time(NULL)); rand() % n`` (module
    docstring), at simulated time ``driver.now()``."""

    def __init__(self, driver, pace: float, epoch: int = 0):
        self.driver = driver
        self.pace = float(pace)
        self.epoch = int(epoch)
        self._second = None
        self._value = 0

    def second(self, now: float) -> int:
        """The emulated wall-clock second of a draw at simulated time ``now``."""
        return self.epoch + math.floor(now / self.pace)

    def choice(self, seq: Sequence):
        """The element of the non-empty ``seq`` the original would draw now."""
        s = self.second(self.driver.now())
        if s != self._second:
            self._second, self._value = s, CRand(s).rand()
        return seq[self._value % len(seq)]


def from_params(params: dict, driver) -> Optional[WallClockDraws]:
    """The emulated draws the strategy ``params`` ask for, or None (the default: the
    robot's seeded generator).

    Raises:
        PatrolInputError: a pace that is not a number >= 0, or an epoch that is not an
            integer.
    """
    pace = params.get(PACE_PARAM, 0)
    try:
        pace = float(pace)
    except (TypeError, ValueError):
        pace = float("nan")
    if not pace >= 0 or math.isinf(pace):
        raise PatrolInputError(f"param {PACE_PARAM}: expected a number >= 0 (0: off), got "
                               f"{params.get(PACE_PARAM)!r}")
    epoch = params.get(EPOCH_PARAM, 0)
    if isinstance(epoch, bool) or not isinstance(epoch, int):
        raise PatrolInputError(f"param {EPOCH_PARAM}: expected an integer, got {epoch!r}")
    return WallClockDraws(driver, pace, epoch) if pace > 0 else None
