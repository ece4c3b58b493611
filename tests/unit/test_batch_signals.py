"""A signal that lands while a batch starts a run (scripts/start_experiments.py --batch):
the run's process exists, so it must be in the running table, stopped and listed as
interrupted, never left behind as "never started"."""
import os
import signal
import subprocess
import sys
import time

import pytest

from patrolling_sim.runner import batch
from patrolling_sim.runner.config import ExperimentConfig

#: stands in for start_experiments.py: runs until SIGINT, then exits 130 as the runner does;
#: like it (scripts/early_signal.py) unblocks the signals the batch held once it handles them
CHILD = """import signal, sys, time
signal.signal(signal.SIGINT, lambda *a: sys.exit(130))
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
print("started", flush=True)
time.sleep(60)
"""

SCRIPTS = os.path.join(os.path.dirname(__file__), "..", "..", "scripts")

#: a program whose start-up (before early_signal.install) takes a second
SLOW_START = """import sys, time
time.sleep(1.0)
sys.path.insert(0, {scripts!r})
import early_signal
early_signal.install("slow.py")
time.sleep(60)
"""


def test_a_signal_during_the_childs_start_up_waits_for_its_handlers(tmp_path):
    """SIGINT sent right after the batch starts a run, while the run's interpreter is still
    loading (here: for a second): held, it reaches the program's early handler, which exits
    130 with its one line. Without holding, it raised KeyboardInterrupt in the start-up:
    exit 1 and a traceback (a loaded CI machine showed it)."""
    child = tmp_path / "slow.py"
    child.write_text(SLOW_START.format(scripts=os.path.abspath(SCRIPTS)))
    p = batch.spawn_with_signals_held([sys.executable, str(child)], stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT, start_new_session=True)
    try:
        os.kill(p.pid, signal.SIGINT)
        out, _ = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    text = out.decode(errors="replace")
    assert p.returncode == 130, text
    assert text.strip() == "slow.py: interrupted by SIGINT before the run started", text
    # and this process's own mask is as it was
    assert not signal.pthread_sigmask(signal.SIG_BLOCK, set()) & batch.HELD_SIGNALS


def test_signal_hold_defers_and_raises_on_leaving():
    hold = batch.SignalHold()
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
    monkeypatch.setattr(batch.subprocess, "Popen", popen_hit_by_sigint)
    hold = batch.SignalHold()

    def on_signal(signum, frame):
        if hold.holding():
            hold.defer()
            return
        raise KeyboardInterrupt
    old = signal.signal(signal.SIGINT, on_signal)
    try:
        configs = [ExperimentConfig(), ExperimentConfig()]
        with pytest.raises(batch.BatchInterrupted) as e:
            batch.run_batch(configs, 1, str(child), out=lambda *_: None, hold=hold)
    finally:
        signal.signal(signal.SIGINT, old)
    first, second = e.value.results
    assert len(started) == 1
    assert first is not None and first[1] == 130 and first[2] == "interrupted"
    assert second is None                      # never started
    assert started[0].poll() == 130            # stopped, not left running
