"""The scripts' log lines (``warning: ...``) without renaming Python's levels process-wide:
the runner also runs a ROS node in its process, and rosgraph's log handler looks records up
by the standard level names (a renamed WARNING made a rospy warning raise KeyError there)."""
import io
import logging

import pytest

from patrolling_sim.common.cli import LowercaseLevelFormatter, setup_logging


def test_setup_logging_keeps_the_standard_level_names():
    setup_logging()
    for lvl, name in ((logging.DEBUG, "DEBUG"), (logging.INFO, "INFO"),
                      (logging.WARNING, "WARNING"), (logging.ERROR, "ERROR")):
        assert logging.getLevelName(lvl) == name


def test_lines_show_the_level_in_lower_case():
    buf = io.StringIO()
    handler = logging.StreamHandler(buf)
    handler.setFormatter(LowercaseLevelFormatter("%(levelname)s: %(message)s"))
    log = logging.getLogger("patrolling_sim.tests.cli_logging")
    log.addHandler(handler)
    log.propagate = False
    try:
        log.warning("disk %s", "full")
        log.error("gone")
    finally:
        log.removeHandler(handler)
    assert buf.getvalue() == "warning: disk full\nerror: gone\n"


def test_rosgraph_handler_takes_a_warning_after_setup_logging():
    roslogging = pytest.importorskip("rosgraph.roslogging",
                                     reason="rosgraph (Debian: python3-rosgraph) missing")
    setup_logging()
    out, err = io.StringIO(), io.StringIO()
    handler = roslogging.RosStreamHandler(colorize=False, stdout=out, stderr=err)
    record = logging.LogRecord("rospy.internal", logging.WARNING, __file__, 1,
                               "Inbound TCP/IP connection failed: %s", ("closed",), None)
    handler.emit(record)                    # raised KeyError: 'warning' before
    assert "Inbound TCP/IP connection failed: closed" in out.getvalue() + err.getvalue()
