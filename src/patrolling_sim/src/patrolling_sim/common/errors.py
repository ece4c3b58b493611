"""Exception types of the pure core.

Every error caused by user input (a file, a parameter, a command-line argument) is a
:class:`PatrolInputError` whose message is one line naming the culprit (file and line, or
argument) and what is wrong with it. Command-line tools print that line and exit non-zero;
no traceback is shown to the user.

The base class is the navigation package's public input error,
``spqrel_nav_lite.errors.InputError`` (the navigation package, whose map loader
``spqrel_nav_lite.mapio`` the core uses, must not depend on this one), so that one ``except
PatrolInputError`` catches map errors (``spqrel_nav_lite.errors.MapFormatError``), graph
errors and every other input error.
"""
from spqrel_nav_lite.errors import InputError as PatrolInputError


class GraphFormatError(PatrolInputError):
    """A ``.graph`` file is malformed."""


class StaleRouteError(PatrolInputError):
    """An MSP route file does not describe a valid closed walk on the current graph."""
