"""Batch files for ``start_experiments.py --batch FILE``.

A batch file is YAML in one of two shapes:

1. a list of configurations (each a mapping with the keys of
   :mod:`patrolling_sim.runner.config`)::

       - {map: grid, robots: 4, alg: CGG, timeout: 300}
       - {map: grid, robots: 4, alg: SEBS, timeout: 300}

2. a grid: ``base`` (common keys) and ``grid`` (key -> list of values); the cartesian
   product of the grid's lists, in file order, expands into the list::

       base: {map: grid, loc: fake_localization, timeout: 300}
       grid: {alg: [CR, CGG, SEBS], robots: [2, 4], seed: [1, 2, 3]}   # 18 runs

Running a batch (:func:`run_batch`): each run is ``start_experiments.py --headless`` in a
process (and session) of its own, ``parallel`` at a time; a signal stops the running ones
and the table (:func:`print_batch_table`) lists every run as finished, interrupted or never
started.
"""
import contextlib
import itertools
import os
import signal
import subprocess
import sys
import time

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import read_yaml
from patrolling_sim.runner.config import ExperimentConfig
import shutil
import tempfile


def load_batch(path, base=None):
    """Return the list of ExperimentConfig (not yet validated) described by ``path``."""
    return expand_batch(read_yaml(path, "batch file"), path, base)


def expand_batch(data, source="batch", base=None):
    base_cfg = base or ExperimentConfig()
    if isinstance(data, list):
        entries = data
    elif isinstance(data, dict) and "grid" in data:
        unknown = set(data) - {"base", "grid"}
        if unknown:
            raise PatrolInputError(f"{source}: unknown top-level key '{sorted(unknown)[0]}' "
                                   f"(a grid batch has 'base' and 'grid')")
        common = data.get("base") or {}
        grid = data["grid"]
        if not isinstance(common, dict) or not isinstance(grid, dict) or not grid:
            raise PatrolInputError(f"{source}: 'base' must be a mapping and 'grid' a non-empty "
                                   f"mapping of key -> list of values")
        keys = list(grid)
        lists = []
        for k in keys:
            v = grid[k]
            if not isinstance(v, list) or not v:
                raise PatrolInputError(f"{source}: grid key '{k}' must be a non-empty list")
            lists.append(v)
        entries = [dict(common, **dict(zip(keys, combo))) for combo in itertools.product(*lists)]
    else:
        raise PatrolInputError(f"{source}: a batch is a list of configurations or a mapping "
                               f"with 'base' and 'grid'")
    out = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise PatrolInputError(f"{source}: entry {i + 1} is not a mapping")
        out.append(base_cfg.updated(entry, f"{source}: entry {i + 1}"))
    if not out:
        raise PatrolInputError(f"{source}: the batch is empty")
    return out


def exit_status(returncode):
    """A child's exit status as a shell reports it: a death by signal N (Popen's -N, e.g. a
    SIGINT that arrived before the child's interpreter had installed its handlers) is
    128 + N, so 130 / 143 mean interrupted whether the child handled the signal or not."""
    return 128 - returncode if returncode is not None and returncode < 0 else returncode


class SignalHold:
    """Holds the interruption a signal handler would raise while a run is being started, so
    that a run whose process exists is always in the table of running ones (and is stopped
    and listed as interrupted): the handler asks :meth:`holding` and, if so, calls
    :meth:`defer` instead of raising; leaving :meth:`hold` raises it."""

    def __init__(self):
        self._depth = 0
        self._pending = False

    def holding(self):
        return self._depth > 0

    def defer(self):
        self._pending = True

    @contextlib.contextmanager
    def hold(self):
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            if not self._depth and self._pending:
                self._pending = False
                raise KeyboardInterrupt


#: the signals a batch forwards to its runs (and holds while starting one)
HELD_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM})


def spawn_with_signals_held(args, **popen_kwargs) -> subprocess.Popen:
    """``subprocess.Popen`` with SIGINT and SIGTERM blocked in the child until it unblocks
    them (``scripts/early_signal.py`` does, once its handlers are installed). A signal sent
    to the child before that stays pending instead of interrupting the interpreter's start-up
    (exit 1 and a traceback, not the run's 130 / 143: seen under load when a batch was
    interrupted just after starting a run). Blocked here for the few microseconds of the
    fork too; a signal to this process meanwhile is delivered when the mask is restored."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS)
    try:
        return subprocess.Popen(args, **popen_kwargs)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _read_run_log(logf):
    """(lines, last "results:" line or "") of a finished run's log file, which it closes."""
    logf.seek(0)
    lines = logf.read().splitlines()
    logf.close()
    return lines, next((l for l in reversed(lines) if l.startswith("results:")), "")


def run_batch(configs, parallel, argv0, out=print, hold=None):
    """Run validated configurations, ``parallel`` at a time, each in its own process
    (each with its own ROS master). Returns the list of (config, exit code, result line).
    ``hold``: the :class:`SignalHold` the caller's signal handler consults (a run's start,
    from its log file to its entry in the running table, is not cut by a signal)."""
    hold = hold or SignalHold()
    pending = list(enumerate(configs))
    running = {}
    results = [None] * len(configs)
    tmpdir = tempfile.mkdtemp(prefix="patrol_batch_")
    done = 0
    try:
        while pending or running:
            while pending and len(running) < parallel:
                with hold.hold():
                    i, cfg = pending.pop(0)
                    path = os.path.join(tmpdir, f"run_{i}.yaml")
                    cfg.save(path)
                    logf = open(os.path.join(tmpdir, f"run_{i}.out"), "w+")
                    p = spawn_with_signals_held(
                        [sys.executable, argv0, "--headless", "--config", path], stdout=logf,
                        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                        start_new_session=True)
                    running[i] = (p, logf, time.monotonic())
            time.sleep(0.5)
            for i, (p, logf, t0) in list(running.items()):
                if p.poll() is None:
                    continue
                lines, res = _read_run_log(logf)
                why = next((l for l in reversed(lines) if l.startswith("result:")
                            or ": error:" in l), "")
                results[i] = (configs[i], exit_status(p.returncode), why, res,
                              time.monotonic() - t0)
                del running[i]
                done += 1
                c = configs[i]
                out(f"[{done}/{len(configs)}] run {i + 1}: {c.map_name} N={c.robots} {c.alg} "
                    f"seed={c.seed} -> exit {exit_status(p.returncode)} "
                    f"({time.monotonic() - t0:.0f} s) {res}")
    except KeyboardInterrupt:
        out("batch interrupted: stopping running experiments")
        for i, (p, logf, t0) in running.items():
            try:
                os.kill(p.pid, signal.SIGINT)
            except OSError:
                pass
        for i, (p, logf, t0) in running.items():
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
            _, res = _read_run_log(logf)
            results[i] = (configs[i], exit_status(p.returncode), "interrupted", res,
                          time.monotonic() - t0)
        raise BatchInterrupted(results)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
    return results


class BatchInterrupted(Exception):
    """The batch was interrupted; ``results`` as :func:`run_batch` returns them (None for
    runs never started)."""

    def __init__(self, results):
        super().__init__("batch interrupted")
        self.results = results


def print_batch_table(results, out=print):
    out("")
    out(f"{'#':>3}  {'map':<14} {'N':>3} {'alg':<6} {'seed':>5} {'exit':>4}  {'wall s':>7}  result")
    for k, r in enumerate(results):
        if r is None:
            out(f"{k + 1:>3}  {'-':<14} {'':>3} {'':<6} {'':>5} {'':>4}  {'':>7}  never started")
            continue
        cfg, code, why, res, wall = r
        out(f"{k + 1:>3}  {cfg.map_name:<14} {cfg.robots:>3} {cfg.alg:<6} {cfg.seed:>5} "
            f"{code:>4}  {wall:>7.0f}  {res[len('results: '):] if res else why}")
