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
import errno
import os

from spqrel_nav_lite.errors import InputError as PatrolInputError


class GraphFormatError(PatrolInputError):
    """A ``.graph`` file is malformed."""


class StaleRouteError(PatrolInputError):
    """An MSP route file does not describe a valid closed walk on the current graph."""


class NoSpaceError(Exception):
    """A file could not be written because its file system is full (ENOSPC, or a quota:
    EDQUOT). Not an input error: the run itself was valid. The message is one line naming
    the path and the space left on its file system.

    Attributes:
        path: the file (or files, as ``<prefix>_*``) that could not be written.
        free: bytes still available to this user on that file system (None: unknown).
    """

    def __init__(self, path):
        self.path = path
        self.free = free_bytes(path)
        free = "unknown space" if self.free is None else f"{self.free} bytes"
        super().__init__(f"no space left on device writing {path} ({free} free on its file "
                         "system)")


def is_no_space(exc) -> bool:
    """True if ``exc`` is an OSError that says the file system is full (ENOSPC, EDQUOT)."""
    return isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT)


def free_bytes(path):
    """Bytes available to this user on the file system that holds ``path`` (or its nearest
    existing parent folder; a glob-like ``<prefix>_*`` works too); None if that cannot be
    read."""
    folder = os.path.abspath(path)
    while folder and not os.path.isdir(folder):
        parent = os.path.dirname(folder)
        if parent == folder:
            return None
        folder = parent
    try:
        st = os.statvfs(folder)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize
