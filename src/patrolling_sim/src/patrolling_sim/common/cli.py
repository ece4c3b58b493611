"""Command-line plumbing shared by the project's scripts.

- :class:`CliParser`: argparse parser whose errors are one line (no usage dump), exit 2.
- :func:`run_main`: runs a ``main(argv)``; a :class:`PatrolInputError` (or an OSError on a
  user-named file) becomes ``<prog>: error: <one line>`` on stderr and exit status 2; a
  full disk (:class:`NoSpaceError`, or an OSError ENOSPC/EDQUOT) one line and exit 1;
  Ctrl-C exits 130 without a traceback.
"""
import argparse
import logging
import sys

from patrolling_sim.common.errors import NoSpaceError, PatrolInputError, is_no_space


class CliParser(argparse.ArgumentParser):
    def error(self, message):
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        sys.exit(2)


class LowercaseLevelFormatter(logging.Formatter):
    """``warning: message`` lines: the level in lower case on this handler only. Renaming
    the levels process-wide (``logging.addLevelName``) broke rosgraph's log handler in the
    runner's own ROS node, which looks records up by the standard names: a rospy warning
    there raised ``KeyError: 'warning'`` in rospy's thread."""

    def format(self, record):
        name = record.levelname
        record.levelname = name.lower()
        try:
            return super().format(record)
        finally:
            record.levelname = name


def setup_logging(verbose=False):
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(LowercaseLevelFormatter("%(levelname)s: %(message)s"))
    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO, handlers=[handler])


def run_main(main, prog, argv=None):
    try:
        rc = main(sys.argv[1:] if argv is None else argv)
    except PatrolInputError as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return 2
    except NoSpaceError as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return 1
    except OSError as e:
        if not is_no_space(e):
            raise
        sys.stderr.write(f"{prog}: error: {NoSpaceError(e.filename or '?')}\n")
        return 1
    except KeyboardInterrupt:
        sys.stderr.write(f"{prog}: interrupted\n")
        return 130
    return 0 if rc is None else rc
