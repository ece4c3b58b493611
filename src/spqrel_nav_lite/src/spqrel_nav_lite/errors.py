"""Exception types of spqrel_nav_lite's pure modules.

An error caused by user input (a map file, a parameter) is an :class:`InputError` whose
message is one line naming the culprit and what is wrong with it. patrolling_sim uses the
same class for its own input errors (``patrolling_sim.common.errors.PatrolInputError``), so one
``except`` catches both.
"""


class InputError(Exception):
    """Bad user input. ``str(err)`` is a single self-contained line."""

    def __init__(self, message):
        super().__init__(" ".join(str(message).split("\n")))


class MapFormatError(InputError):
    """A map_server yaml or its image is missing or malformed."""
