"""Exception types of the pure core.

Every error caused by user input (a file, a parameter, a command-line argument) is a
:class:`PatrolInputError` whose message is one line naming the culprit (file and line, or
argument) and what is wrong with it. Command-line tools print that line and exit non-zero;
no traceback is shown to the user.
"""


class PatrolInputError(Exception):
    """Bad user input. ``str(err)`` is a single self-contained line."""

    def __init__(self, message):
        super().__init__(" ".join(str(message).split("\n")))


class GraphFormatError(PatrolInputError):
    """A ``.graph`` file is malformed."""


class MapFormatError(PatrolInputError):
    """A map_server yaml or its image is missing or malformed."""


class StaleRouteError(PatrolInputError):
    """An MSP route file does not describe a valid closed walk on the current graph."""
