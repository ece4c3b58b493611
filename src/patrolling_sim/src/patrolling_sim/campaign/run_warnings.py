"""Warnings logged during one graph-mode run of a campaign, kept for the run's record."""
import logging
import threading
from typing import Dict, List

#: the logger whose records a :class:`RunWarnings` collects (the whole package's)
PACKAGE_LOGGER = "patrolling_sim"


class RunWarnings(logging.Handler):
    """The warnings the package logs during one graph-mode run of a campaign (e.g. DTAG's or
    DTAP's idleness estimate that no longer fits the original's int16 payload), kept for
    the run's state record instead of printed: a worker's log lines reach the campaign's
    terminal without saying which run they came from (a full reference campaign printed
    235 of them). A context manager; at most :data:`MAX_LINES` lines, then a count; every
    message is also counted in :attr:`counts` (the campaign's validation of its runs reports
    each warning once with the number of runs, :func:`patrolling_sim.campaign.spec.load_campaign`).

    The package's logger stops propagating while any run of the process is inside one (a
    worker with several threads runs several at once, ending in any order); the first to
    enter saves its setting, the last to leave restores it."""
    MAX_LINES = 20
    _lock = threading.Lock()
    _active = 0                 # runs inside one, in this process
    _saved_propagate = True

    def __init__(self):
        super().__init__(logging.WARNING)
        self._lines: List[str] = []
        self._more = 0
        self._thread = threading.get_ident()
        self.counts: Dict[str, int] = {}        # message -> times logged, in logging order

    @property
    def lines(self) -> List[str]:
        return self._lines + ([f"... and {self._more} more"] if self._more else [])

    def emit(self, record):
        if record.thread != self._thread:       # another run of a multi-threaded worker
            return
        msg = record.getMessage()
        self.counts[msg] = self.counts.get(msg, 0) + 1
        if len(self._lines) < self.MAX_LINES:
            self._lines.append(f"{record.levelname}: {msg}")
        else:
            self._more += 1

    def __enter__(self):
        log = logging.getLogger(PACKAGE_LOGGER)
        with RunWarnings._lock:
            if RunWarnings._active == 0:
                RunWarnings._saved_propagate = log.propagate
                log.propagate = False
            RunWarnings._active += 1
            log.addHandler(self)
        return self

    def __exit__(self, *exc):
        log = logging.getLogger(PACKAGE_LOGGER)
        with RunWarnings._lock:
            log.removeHandler(self)
            RunWarnings._active -= 1
            if RunWarnings._active == 0:
                log.propagate = RunWarnings._saved_propagate
        return False
