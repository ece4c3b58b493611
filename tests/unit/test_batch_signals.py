"""A signal that lands while a batch starts a run (scripts/start_experiments.py --batch):
the run's process exists, so it must be in the running table, stopped and listed as
interrupted, never left behind as "never started" (a CI run of
tests/ros/test_faults.py::test_interrupted_batch_prints_its_table caught the race)."""
import os
import signal
import subprocess
import sys
import time

import pytest

from patrolling_sim.runner import cli
from patrolling_sim.runner.config import ExperimentConfig

#: stands in for start_experiments.py: runs until SIGINT, then exits 130 as the runner does
CHILD = """import signal, sys, time
signal.signal(signal.SIGINT, lambda *a: sys.exit(130))
print("started", flush=True)
time.sleep(60)
"""


def test_signal_hold_defers_and_raises_on_leaving():
    hold = cli.SignalHold()
    assert not hold.holding()
    with pytest.raises(KeyboardInterrupt):
        with hold.hold():
            assert hold.holding()
            hold.defer()
            with hold.hold():                  # nested: raised only when the outer ends
                pass
    assert not hold.holding()
    with hold.hold():                          # nothing deferred: nothing raised
        pass


def test_sigint_during_a_runs_start_stops_and_lists_it(tmp_path, monkeypatch):
    child = tmp_path / "child.py"
    child.write_text(CHILD)
    started = []
    real_popen = subprocess.Popen

    def popen_hit_by_sigint(*a, **kw):
        p = real_popen(*a, **kw)
        started.append(p)
        os.kill(os.getpid(), signal.SIGINT)    # lands before the run is in the table
        time.sleep(0.2)
        return p
    monkeypatch.setattr(cli.subprocess, "Popen", popen_hit_by_sigint)
    hold = cli.SignalHold()

    def on_signal(signum, frame):
        if hold.holding():
            hold.defer()
            return
        raise KeyboardInterrupt
    old = signal.signal(signal.SIGINT, on_signal)
    try:
        configs = [ExperimentConfig(), ExperimentConfig()]
        with pytest.raises(cli.BatchInterrupted) as e:
            cli.run_batch(configs, 1, str(child), out=lambda *_: None, hold=hold)
    finally:
        signal.signal(signal.SIGINT, old)
    first, second = e.value.results
    assert len(started) == 1
    assert first is not None and first[1] == 130 and first[2] == "interrupted"
    assert second is None                      # never started
    assert started[0].poll() == 130            # stopped, not left running
