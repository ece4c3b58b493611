"""Command-line plumbing shared by the project's scripts.

- :class:`CliParser`: argparse parser whose errors are one line (no usage dump), exit 2.
- :func:`run_main`: runs a ``main(argv)``; a :class:`PatrolInputError` (or an OSError on a
  user-named file) becomes ``<prog>: error: <one line>`` on stderr and exit status 2;
  Ctrl-C exits 130 without a traceback.
"""
import argparse
import logging
import sys

from .errors import PatrolInputError


class CliParser(argparse.ArgumentParser):
    def error(self, message):
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        sys.exit(2)


def setup_logging(verbose=False):
    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO,
                        format="%(levelname)s: %(message)s",
                        stream=sys.stderr)
    for lvl in (logging.WARNING, logging.ERROR, logging.INFO, logging.DEBUG):
        logging.addLevelName(lvl, logging.getLevelName(lvl).lower())


def run_main(main, prog, argv=None):
    try:
        rc = main(sys.argv[1:] if argv is None else argv)
    except PatrolInputError as e:
        sys.stderr.write(f"{prog}: error: {e}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(f"{prog}: interrupted\n")
        return 130
    return 0 if rc is None else rc
