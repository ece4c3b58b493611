"""Campaigns (patrolling_sim.campaign.engine): validation of campaign files, a graph-mode
campaign on a 2-worker LocalCluster interrupted and resumed, and the same campaign on a
separately started Dask scheduler + 2 workers."""
import logging
import os
import signal
import socket
import subprocess
import sys
import time

import pandas as pd
import pytest
import yaml

import process_guard  # tests/process_guard.py (tests/conftest.py puts tests/ on the path)
from patrolling_sim.campaign.spec import load_campaign
from patrolling_sim.campaign.store import load_state
from patrolling_sim.common.errors import PatrolInputError

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPT = os.path.join(ROOT, "scripts", "campaign.py")
CAMPAIGN = {"name": "t", "mode": "graph", "fixed": {"duration": 300},
            "grid": {"map": ["grid", "1r5"], "robots": [2], "alg": ["CR", "CGG"]}, "seeds": 3}
METRICS = ["idl_avg", "idl_max", "total_visits", "complete_cycles", "time_avg_idleness",
           "worst_idleness"]


def _grid_cr_campaign(tmp_path, seeds=2, **extra):
    """CAMPAIGN cut to the grid map and CR: ``seeds`` runs."""
    return load_campaign(_write(tmp_path, dict(CAMPAIGN, grid=dict(CAMPAIGN["grid"],
                                                                   map=["grid"], alg=["CR"]),
                                               seeds=seeds, **extra)))


def _write(tmp_path, data, name="c.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    return str(p)


def _env():
    """The environment of the campaign programs the tests start (the packages' source folders
    on PYTHONPATH come from tests/conftest.py)."""
    return dict(os.environ, PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))


@pytest.mark.parametrize("change, words", [
    ({"colour": "red"}, "unknown key 'colour'"),
    ({"grid": {"map": ["grid"], "robotz": [2]}}, "grid.robotz: unknown configuration key"),
    ({"grid": {"map": ["grid"], "alg": []}}, "grid.alg: empty list"),
    ({"grid": {"map": ["grid"], "robots": ["four"]}}, "grid.robots: expected an integer"),
    ({"fixed": {"duration": "long"}}, "fixed.duration: expected a number"),
    ({"grid": {"map": ["grid", "atlantis"]}}, "grid.map: unknown map 'atlantis'"),
    ({"grid": {"map": ["grid"], "alg": ["NOPE"]}}, "alg=NOPE"),
    ({"mode": "cloud"}, "mode: expected one of graph, ros"),
    ({"seeds": 0}, "seeds: expected an integer >= 1"),
])
def test_bad_campaign_files_fail_with_one_line_naming_the_key(tmp_path, change, words):
    data = dict(CAMPAIGN, **change)
    with pytest.raises(PatrolInputError) as e:
        load_campaign(_write(tmp_path, data))
    msg = str(e.value)
    assert words in msg and "\n" not in msg and "c.yaml" in msg


@pytest.mark.parametrize("text, words", [("grid: [unclosed", "not valid YAML"),
                                         ("mode: graph\ngrid: {map: [atlantis]}\n",
                                          "grid.map: unknown map 'atlantis'")])
def test_bad_campaign_file_cli_exit_2_nothing_written(tmp_path, text, words):
    """One line, exit 2, no campaign folder; and nothing left running: the command starts
    its workers' forkserver before it validates the file (to overlap their imports), and that
    server must end with it."""
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, SCRIPT, _write(tmp_path, text), "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(),
                         start_new_session=True)
    _, err = p.communicate()
    assert p.returncode == 2
    assert err.count("\n") == 1 and words in err, err
    assert not out.exists()
    for _ in range(100):                     # the server notices its client's exit at once
        if not process_guard.members(p.pid):   # the command leads its own group
            break
        time.sleep(0.1)
    assert not process_guard.members(p.pid)


def test_validation_warnings_are_given_once_with_their_count(tmp_path, capsys):
    """A warning the runner gives while a campaign's runs are validated comes once, with the
    number of runs it concerns, not once per run; a campaign without one has none; the
    package's logger propagates again afterwards."""
    ros = {"name": "w", "mode": "ros", "seeds": 3,
           "fixed": {"map": "grid", "robots": 4, "alg": "SEBS", "timeout": 100,
                     "attrition": "2@50", "dead_robot_timeout": 60}}
    camp = load_campaign(_write(tmp_path, ros))
    assert len(camp.runs) == 3
    [line] = camp.warnings
    assert line.startswith("--dead-robot-timeout 60 s with robot failures")
    assert line.endswith("(in 3 of the 3 runs)")
    assert "dead-robot-timeout" not in capsys.readouterr().err
    assert logging.getLogger("patrolling_sim").propagate
    ros["fixed"]["dead_robot_timeout"] = 300
    assert load_campaign(_write(tmp_path, ros)).warnings == []
    assert load_campaign(_write(tmp_path, CAMPAIGN)).warnings == []
    # the command prints it once
    p = subprocess.run([sys.executable, SCRIPT, _write(tmp_path, dict(ros, fixed=dict(
        ros["fixed"], dead_robot_timeout=60))), "--dry-run", "--out", str(tmp_path / "o")],
        capture_output=True, text=True, env=_env())
    assert p.returncode == 0, p.stderr
    assert p.stderr.count("campaign.py: warning: --dead-robot-timeout 60 s") == 1, p.stderr


def test_keys_are_stable_and_cover_the_grid(tmp_path):
    path = _write(tmp_path, CAMPAIGN)
    a = load_campaign(path, code={"commit": "abc", "dirty": False})
    b = load_campaign(path, code={"commit": "abc", "dirty": False})
    c = load_campaign(path, code={"commit": "def", "dirty": False})
    assert len(a.runs) == 2 * 2 * 3
    assert [r.key for r in a.runs] == [r.key for r in b.runs]
    assert not {r.key for r in a.runs} & {r.key for r in c.runs}     # code version in the key


def _table(out):
    df = pd.read_csv(os.path.join(out, "runs.csv")).set_index("key").sort_index()
    return df


def _measured(out, df):
    """key -> text of the run's idleness and visits files (the measured data)."""
    res = {}
    for key, prefix in df["prefix"].items():
        res[key] = tuple(open(os.path.join(out, prefix + s)).read()
                         for s in ("_idleness.csv", "_visits.csv"))
    return res


def _info_count(out):
    return sum(f.endswith("_info.csv") for _, _, fs in os.walk(os.path.join(out, "results"))
               for f in fs)


def _signal_group_after_three_runs(cmd, out, sig):
    """Start the campaign command ``cmd`` (writing to ``out``) in a process group of its own,
    send ``sig`` to the whole group once 3 runs are stored (as a terminal's Ctrl-C or a
    batch system's SIGTERM does: the Dask workers get it too); (exit code, output)."""
    proc = subprocess.Popen(cmd + ["--out", out], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=_env(),
                            start_new_session=True)
    state_dir = os.path.join(out, "state")
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if os.path.isdir(state_dir) and len(os.listdir(state_dir)) >= 3:
            os.killpg(proc.pid, sig)
            break
        time.sleep(0.05)
    text, _ = proc.communicate(timeout=300)
    return proc.returncode, text


def test_interrupted_campaign_resumes_to_the_clean_result(tmp_path):
    # hour-long runs: a 300 s graph run now takes a few ms, and all 12 could finish between
    # the third stored run and the SIGINT, so the interruption would not land mid-campaign
    path = _write(tmp_path, dict(CAMPAIGN, fixed={"duration": 3600}))
    clean, resumed = str(tmp_path / "clean"), str(tmp_path / "resumed")
    cmd = [sys.executable, SCRIPT, path, "--workers", "2", "--no-report"]
    p = subprocess.run(cmd + ["--out", clean], capture_output=True, text=True, env=_env(),
                       timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]

    # interrupt once some runs are stored, then resume. SIGINT as a terminal's Ctrl-C sends
    # it: to the whole process group, so the Dask workers get it too
    rc, out = _signal_group_after_three_runs(cmd, resumed, signal.SIGINT)
    done_first = len(load_state(resumed))
    if rc == 130:
        assert "interrupted" in out and 3 <= done_first < 12
        # the workers ignore it (campaign_tasks.IgnoreGroupSignals): no traceback of theirs, no
        # warning about killing them
        assert "Traceback" not in out and "KeyboardInterrupt" not in out, out[-3000:]
        assert "killing" not in out, out[-3000:]
    else:                     # the campaign finished before the signal could land
        assert rc == 0 and done_first == 12
    assert _info_count(resumed) == done_first               # complete files for every record
    p = subprocess.run(cmd + ["--out", resumed], capture_output=True, text=True, env=_env(),
                       timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    assert f"{done_first} already done" in p.stdout or done_first == 12
    a, b = _table(clean), _table(resumed)
    assert list(a.index) == list(b.index) and (b["status"] == "TIMEOUT").all()
    pd.testing.assert_frame_equal(a[METRICS], b[METRICS])
    assert _info_count(resumed) == 12                       # no run executed twice
    assert _measured(clean, a) == _measured(resumed, b)     # seeded runs bit-identical
    # nothing is left to do
    p = subprocess.run(cmd + ["--out", resumed, "--dry-run"], capture_output=True, text=True,
                       env=_env(), timeout=600)
    assert p.returncode == 0 and p.stdout.count(" done ") == 12, p.stdout


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_external_scheduler_gives_the_same_table(tmp_path):
    path = _write(tmp_path, dict(CAMPAIGN, seeds=1))
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    procs = []
    try:
        procs.append(subprocess.Popen(["/usr/bin/dask-scheduler", "--host", "127.0.0.1",
                                       "--port", str(port), "--dashboard-address", ":0"],
                                      env=_env(), stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL, start_new_session=True))
        for k in range(2):
            wd = tmp_path / f"worker{k}"
            wd.mkdir()
            procs.append(subprocess.Popen(["/usr/bin/dask-worker", addr, "--nthreads", "1",
                                           "--local-directory", str(wd), "--no-dashboard"],
                                          env=_env(), cwd=str(wd), stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL, start_new_session=True))
        ext, local = str(tmp_path / "ext"), str(tmp_path / "local")
        p = subprocess.run([sys.executable, SCRIPT, path, "--scheduler", addr, "--no-report",
                            "--out", ext], capture_output=True, text=True, env=_env(),
                           timeout=600)
        assert p.returncode == 0, p.stdout[-1000:] + p.stderr[-2000:]
        p = subprocess.run([sys.executable, SCRIPT, path, "--workers", "2", "--no-report",
                            "--out", local], capture_output=True, text=True, env=_env(),
                           timeout=600)
        assert p.returncode == 0, p.stderr[-2000:]
        a, b = _table(ext), _table(local)
        assert len(a) == 4
        pd.testing.assert_frame_equal(a[METRICS], b[METRICS])
        assert _measured(ext, a) == _measured(local, b)
    finally:
        for pr in procs:
            try:
                os.killpg(pr.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        for pr in procs:
            try:
                pr.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(pr.pid, signal.SIGKILL)


def test_all_expands_to_every_map_and_algorithm(tmp_path):
    from patrolling_sim.common import paths
    from patrolling_sim.algorithms import names
    camp = load_campaign(_write(tmp_path, {"grid": {"map": "all", "alg": "all"}}),
                         code={"commit": "x", "dirty": False})
    assert {r.config["map"] for r in camp.runs} == set(paths.available_maps())
    assert {r.config["alg"] for r in camp.runs} == set(names())


def test_scenario_runs_get_scenario_columns_and_metrics():
    """A run with a failure and a communication model: its row has the scn_* columns (the
    failure time, message counters) and its metrics file the per-failure impact; a run
    without a scenario has neither."""
    from patrolling_sim.campaign.tasks import run_graph_task
    base = dict(map="grid", robots=4, alg="SEBS", duration=900.0, seed=1)
    res = run_graph_task(dict(base, attrition="1@400", comm="bernoulli:p=0.3"))
    m = res["metrics"]
    assert res["status"] == "TIMEOUT"
    assert m["scn_failures"] == 1 and m["scn_first_failure"] == pytest.approx(400.0, abs=1.0)
    assert m["scn_msgs_sent"] > m["scn_msgs_delivered"] > 0
    assert 0.5 < m["scn_delivered_share"] < 0.9            # 30 % loss
    assert m["scn_idl_before"] > 0 and m["scn_idl_after"] > 0
    doc = yaml.safe_load(res["files"][res["prefix"] + "_metrics.yaml"])
    assert [f["robots"] for f in doc["scenario"]["failures"]] == [[1]]
    plain = run_graph_task(base)["metrics"]
    assert not [k for k in plain if k.startswith("scn_")]


def test_row_has_the_longest_silence_of_the_visit_log():
    """runs.csv's longest_silence / longest_silence_robot: the longest time a robot sent no
    visit report (from GO to its first, between two, from its last to the end), recomputed
    here from the run's own visit log."""
    from patrolling_sim.campaign.tasks import run_graph_task
    res = run_graph_task(dict(map="grid", robots=3, alg="RAND", duration=400.0, seed=4))
    log = res["files"][res["prefix"] + "_visits.csv"].split()
    times = {}
    for line in log[1:]:                                  # Time;Robot;Node
        t, rid, _ = line.split(";")
        times.setdefault(int(rid), []).append(float(t))
    gaps = {}
    for rid, ts in times.items():
        edges = [0.0] + sorted(ts) + [400.0]
        gaps[rid] = max(b - a for a, b in zip(edges, edges[1:]))
    m = res["metrics"]
    worst = max(gaps.values())
    assert m["longest_silence"] == pytest.approx(worst, abs=0.06)           # rounded to 0.1
    # ties (a regular grid gives some) go to the lowest id
    assert m["longest_silence_robot"] == min(r for r, g in gaps.items() if g > worst - 0.06)
    assert 0 < m["longest_silence"] < 400


def test_a_runs_warnings_go_to_its_record_not_to_the_terminal(tmp_path, monkeypatch, capsys):
    """What the package logs during a graph run of a campaign (DTAG's int16 clamp, ...) is
    kept with that run: its state record lists the lines (at most 20, then a count),
    runs.csv counts them, the summary says how many runs had some, and nothing is printed."""
    import logging
    from patrolling_sim.graphsim import simulator as graph_sim
    from patrolling_sim.campaign.store import store_result, write_table
    from patrolling_sim.campaign.store import summary_table
    from patrolling_sim.campaign.tasks import run_graph_task
    real_run = graph_sim.GraphSimulator.run

    def noisy_run(self, *a, **kw):
        for i in range(23):
            logging.getLogger("patrolling_sim.algorithms.dta_common").warning("clamp %d", i)
        return real_run(self, *a, **kw)
    monkeypatch.setattr(graph_sim.GraphSimulator, "run", noisy_run)
    printed = []                # what would reach the worker's stderr: the root logger

    class Root(logging.Handler):
        def emit(self, record):
            printed.append(record)
    root = Root()
    logging.getLogger().addHandler(root)
    try:
        res = run_graph_task(dict(map="grid", robots=2, alg="DTAG", duration=60.0, seed=0))
    finally:
        logging.getLogger().removeHandler(root)
    assert res["warnings"] == [f"WARNING: clamp {i}" for i in range(20)] + ["... and 3 more"]
    assert not printed and capsys.readouterr().err == ""
    assert logging.getLogger("patrolling_sim").propagate          # restored after the run
    monkeypatch.setattr(graph_sim.GraphSimulator, "run", real_run)
    quiet = run_graph_task(dict(map="grid", robots=2, alg="DTAG", duration=60.0, seed=1))
    assert "warnings" not in quiet
    camp = load_campaign(_write(tmp_path, CAMPAIGN))
    out = str(tmp_path / "out")
    state = {camp.runs[0].key: store_result(out, camp.runs[0], res, camp),
             camp.runs[1].key: store_result(out, camp.runs[1], quiet, camp)}
    rec = yaml.safe_load(open(os.path.join(out, "state", camp.runs[0].key + ".yaml")))
    assert rec["warnings"] == res["warnings"]
    write_table(out, camp, state)
    df = pd.read_csv(os.path.join(out, "runs.csv"))
    assert list(df["warnings"][:2]) == [21, 0]
    assert "warnings: 1 run(s) logged warnings" in summary_table(out)


def test_runs_table_reads_as_pandas_own_and_summary_agrees_with_pandas(tmp_path):
    """runs.csv is written without pandas (campaign_store.write_table): pandas reads it as
    the frame it would have written itself from the same rows (finished, crashed, not run;
    NaN and None metrics, JSON parameters, booleans, a comma in a text), and the printed
    summary's counts and means are pandas' groupby of it."""
    import math
    from patrolling_sim.campaign.store import summary_table, table_rows, write_table
    camp = load_campaign(_write(tmp_path, dict(CAMPAIGN, fixed={"duration": 300,
                                                                "params": {"a": [1, 2]}})))
    out = str(tmp_path / "out")
    os.makedirs(out)
    state = {}
    for i, spec in enumerate(camp.runs[:9]):
        status = {4: "CRASHED", 5: "FAIL", 6: "CYCLES"}.get(i, "TIMEOUT")
        metrics = {} if status == "CRASHED" else {
            "idl_avg": 10.0 + i / 3, "idl_max": 50 + i, "total_visits": 100 + i,
            "time_avg_idleness": float("nan") if i == 2 else 7.25 * i,
            "longest_silence_robot": None if i == 3 else i}
        state[spec.key] = {"status": status, "rc": 1 if status == "CRASHED" else 0,
                           "prefix": f"results/x,{i}", "wall": 0.5, "cpu_s": 0.25,
                           "metrics": metrics, "warnings": ["w"] * (i % 2)}
    path = write_table(out, camp, state)
    ours = pd.read_csv(path)
    # the frame pandas writes from the same rows
    rows = table_rows(camp, state)
    assert [r["key"] for r in rows] == [r.key for r in camp.runs]
    assert rows[0]["params"] == '{"a": [1, 2]}' and rows[0]["warnings"] == 0
    assert rows[-1]["status"] == "NOT_RUN" and "idl_avg" not in rows[-1]
    pd.DataFrame(rows).to_csv(tmp_path / "pandas.csv", index=False)
    theirs = pd.read_csv(tmp_path / "pandas.csv")
    pd.testing.assert_frame_equal(ours, theirs)
    assert (ours["status"] == "NOT_RUN").sum() == len(camp.runs) - 9
    text = summary_table(out).splitlines()
    ok = theirs[theirs["status"].isin(["TIMEOUT", "CYCLES"])]
    g = ok.groupby(["map", "robots", "alg"])
    expect = g.agg(runs=("key", "count"), avg=("idl_avg", "mean"), mx=("idl_max", "mean"),
                   visits=("total_visits", "mean"), tavg=("time_avg_idleness", "mean"))
    assert text[0].split() == ["map", "robots", "alg", "runs", "avg_idleness", "max_idleness",
                               "visits", "time_avg_idleness"]
    body = [line.split() for line in text[1:1 + len(expect)]]
    assert [(m, int(n), a) for m, n, a, *_ in body] == list(expect.index)
    for cells, (_, e) in zip(body, expect.iterrows()):
        assert int(cells[3]) == e["runs"]
        for got, want in zip(cells[4:], (e["avg"], e["mx"], e["visits"], e["tavg"])):
            assert not math.isnan(want) and float(got) == pytest.approx(round(want, 2))
    counts = theirs["status"].value_counts().to_dict()
    assert text[1 + len(expect)] == "status: " + ", ".join(f"{k} {v}" for k, v in
                                                           sorted(counts.items()))
    assert text[-1].startswith("warnings: 4 run(s) logged warnings")


def test_overlapping_runs_restore_the_loggers_propagation():
    """Two runs of a multi-threaded worker, the first ending before the second: the package's
    logger propagates again once both are done, and each run keeps only its own thread's
    warnings."""
    import logging
    import threading
    from patrolling_sim.campaign.tasks import RunWarnings
    log = logging.getLogger("patrolling_sim.algorithms.dta_common")
    first = RunWarnings().__enter__()
    got = {}

    def other_run():
        second = got["second"] = RunWarnings().__enter__()
        log.warning("second's")
        got["entered"].set()
        got["first_done"].wait(60)
        second.__exit__(None, None, None)
    got["entered"], got["first_done"] = threading.Event(), threading.Event()
    th = threading.Thread(target=other_run)
    th.start()
    assert got["entered"].wait(60)
    log.warning("first's")
    first.__exit__(None, None, None)
    assert not logging.getLogger("patrolling_sim").propagate     # the second still runs
    got["first_done"].set()
    th.join(60)
    assert logging.getLogger("patrolling_sim").propagate
    assert first.lines == ["WARNING: first's"] and got["second"].lines == ["WARNING: second's"]


def test_runs_with_one_time_stamp_keep_their_files_apart(tmp_path):
    """Runs stored within one second share a prefix: each gets its own suffix, across calls
    (a resumed campaign starts with an empty suffix memory and must not overwrite files)."""
    from patrolling_sim.campaign.store import store_result
    camp = load_campaign(_write(tmp_path, CAMPAIGN))
    out = str(tmp_path / "out")

    def result(i):
        p = "grid_2/CR/host/20260101_000000"
        return {"prefix": p, "status": "TIMEOUT", "metrics": {"idl_avg": float(i)},
                "files": {p + "_info.csv": f"run {i}\n", p + "_idleness.csv": f"{i}\n"}}

    first = {}
    recs = [store_result(out, camp.runs[i], result(i), camp, first) for i in range(3)]
    recs += [store_result(out, camp.runs[i], result(i), camp, {}) for i in range(3, 5)]
    recs.append(store_result(out, camp.runs[5], result(5), camp))
    prefixes = [r["prefix"] for r in recs]
    assert len(set(prefixes)) == 6
    for i, p in enumerate(prefixes):
        assert open(os.path.join(out, p + "_info.csv")).read() == f"run {i}\n"
    assert not [f for _, _, fs in os.walk(out) for f in fs if f.endswith(".part")]


def test_a_signal_after_the_last_run_interrupts_nothing(tmp_path):
    """SIGINT while the last run is being stored: the campaign finishes (not "interrupted"),
    table and provenance written; SIGINT at the first of several runs: interrupted."""
    import io
    from patrolling_sim.campaign.engine import run_campaign
    camp = _grid_cr_campaign(tmp_path)
    assert len(camp.runs) == 2

    def kill_at(k):
        seen = []

        def on_record(rec):
            seen.append(rec)
            if len(seen) == k:
                os.kill(os.getpid(), signal.SIGINT)
        return on_record

    out = str(tmp_path / "late")
    log = io.StringIO()
    before = signal.getsignal(signal.SIGINT)   # SIG_IGN in a background shell (CI)
    res = run_campaign(camp, out, workers=1, stream=log, on_record=kill_at(2))
    assert res["ran"] == 2 and not res["interrupted"] and res["signal"] is None
    assert "after the last run: finished" in log.getvalue() and "interrupted" not in log.getvalue()
    assert not yaml.safe_load(open(os.path.join(out, "provenance.yaml")))["interrupted"]
    assert set(_table(out)["status"]) == {"TIMEOUT"}
    # the caller's handler is back
    assert signal.getsignal(signal.SIGINT) == before

    camp4 = load_campaign(_write(tmp_path, dict(CAMPAIGN, grid=dict(CAMPAIGN["grid"],
                                                                    map=["grid"], alg=["CR"]),
                                                seeds=40, fixed={"duration": 3600}),
                                 name="c4.yaml"))
    out = str(tmp_path / "early")
    log = io.StringIO()
    res = run_campaign(camp4, out, workers=1, stream=log, on_record=kill_at(1))
    assert res["interrupted"] and res["signal"] == signal.SIGINT and res["ran"] < 40
    assert "interrupted after" in log.getvalue()
    assert yaml.safe_load(open(os.path.join(out, "provenance.yaml")))["interrupted"]


def test_sigterm_to_the_process_group_stops_cleanly(tmp_path):
    """A SIGTERM to the campaign's whole process group (``kill -TERM -PGID``, a batch system
    ending the job) reaches the Dask workers too: the campaign stops as on its own SIGTERM
    (exit 143, "interrupted", complete files for every record) and no worker dies in a
    traceback or is restarted by its Nanny."""
    path = _write(tmp_path, dict(CAMPAIGN, fixed={"duration": 3600}))
    out = str(tmp_path / "term")
    rc, text = _signal_group_after_three_runs(
        [sys.executable, SCRIPT, path, "--workers", "2", "--no-report"], out, signal.SIGTERM)
    done = len(load_state(out))
    if rc == 143:
        assert "interrupted" in text and 3 <= done < 12
        for word in ("Traceback", "Restarting worker", "killing", "ERROR"):
            assert word not in text, text[-3000:]
    else:                     # the campaign finished before the signal could land
        assert rc == 0 and done == 12, text[-3000:]
    assert _info_count(out) == done
    assert (_table(out)["status"] == "NOT_RUN").sum() == 12 - done


def _live_children():
    """Ids of the live (not zombie) processes this process started, directly or through
    multiprocessing's forkserver (which forks the LocalCluster's workers), except the
    resource tracker and the forkserver themselves: both are started with the first
    cluster and live as long as this process by design (Linux /proc)."""
    from patrolling_sim.runner.proctree import proc_stat
    me, kids = os.getpid(), {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            st = proc_stat(d)
            try:
                with open(f"/proc/{d}/cmdline", "rb") as f:
                    cmd = f.read()
            except OSError:
                continue
            if st is not None and st.state != "Z":
                kids.setdefault(st.ppid, []).append((int(d), cmd))
    out = set()
    for pid, cmd in kids.get(me, []):
        if b"multiprocessing.resource_tracker" in cmd:
            continue
        if b"multiprocessing.forkserver" in cmd:     # the server: its children are workers
            out.update(p for p, _ in kids.get(pid, []))
        else:
            out.add(pid)
    return out


def test_a_signal_while_the_cluster_starts_stops_it(tmp_path, monkeypatch):
    """The LocalCluster starts in a thread while the client prepares; SIGINT in that window
    stops the campaign: no run, the cluster's worker processes stopped, table and provenance
    written, interrupted."""
    import io
    import patrolling_sim.campaign.engine as campaign_mod
    camp = _grid_cr_campaign(tmp_path)
    real = campaign_mod._package_versions

    def versions_then_ctrl_c():
        os.kill(os.getpid(), signal.SIGINT)
        return real()

    before = _live_children()
    monkeypatch.setattr(campaign_mod, "_package_versions", versions_then_ctrl_c)
    out = str(tmp_path / "starting")
    log = io.StringIO()
    res = campaign_mod.run_campaign(camp, out, workers=1, stream=log)
    assert res["interrupted"] and res["signal"] == signal.SIGINT and res["ran"] == 0
    assert "interrupted after 0 run(s)" in log.getvalue()
    assert set(_table(out)["status"]) == {"NOT_RUN"}
    assert yaml.safe_load(open(os.path.join(out, "provenance.yaml")))["interrupted"]
    # the start was waited for (not left running on its own after the return) ...
    import threading
    assert not [t for t in threading.enumerate() if t.name == "campaign-cluster-start"]
    # ... and the cluster it started was closed
    for _ in range(100):                     # the nanny's worker process may take a moment
        if _live_children() <= before:
            break
        time.sleep(0.1)
    assert _live_children() <= before


def _children_of(pid):
    """Ids of the live (not zombie) children of ``pid`` (Linux /proc)."""
    from patrolling_sim.runner.proctree import proc_stat
    out = []
    for d in os.listdir("/proc"):
        st = proc_stat(d) if d.isdigit() else None
        if st is not None and st.ppid == pid and st.state != "Z":
            out.append(int(d))
    return out


def test_local_workers_are_forked_from_a_preloaded_server(tmp_path):
    """The LocalCluster's workers are children of multiprocessing's forkserver, which has
    imported distributed and the simulator (campaign.WORKER_PRELOAD), not interpreters
    spawned by the client: while a run is stored, the forkserver has a live child and the
    client no worker of its own."""
    import io
    from multiprocessing import forkserver
    import patrolling_sim.campaign.engine as campaign_mod
    camp = _grid_cr_campaign(tmp_path)
    seen = []

    def look(rec):
        server = forkserver._forkserver._forkserver_pid
        seen.append((server, _children_of(server) if server else [], _live_children()))

    res = campaign_mod.run_campaign(camp, str(tmp_path / "out"), workers=1,
                                    stream=io.StringIO(), on_record=look)
    assert res["ran"] == 2 and not res["interrupted"]
    server, workers, own = seen[0]
    assert server is not None and len(workers) == 1
    assert own == set(workers)               # no worker of the client's own
    with open(f"/proc/{server}/cmdline", "rb") as f:
        assert b"multiprocessing.forkserver" in f.read()
    import dask
    assert dask.config.get("distributed.worker.multiprocessing-method") == "forkserver"


def test_worker_worlds_freeze_the_workers_start_up_objects_once():
    """A worker's first graph run freezes what the process holds (gc.freeze: its full
    garbage collections then skip Dask's and the simulator's start-up objects); later runs
    reuse its WorldCache and freeze nothing more; outside a worker nothing is frozen."""
    import gc
    from distributed import Client, LocalCluster
    from patrolling_sim.campaign.tasks import worker_worlds

    def probe():
        gc.unfreeze()
        first = worker_worlds()
        frozen_first = gc.get_freeze_count()
        gc.unfreeze()
        again = worker_worlds()
        return first is again, frozen_first, gc.get_freeze_count()

    try:
        gc.unfreeze()
        worker_worlds()                          # not in a Dask task: a new cache, no freeze
        assert gc.get_freeze_count() == 0
        with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                          dashboard_address=":0") as cluster, Client(cluster) as client:
            same, frozen_first, frozen_again = client.submit(probe, pure=False).result()
        assert same and frozen_first > 0 and frozen_again == 0
    finally:
        gc.unfreeze()


def test_progress_lines_are_rate_limited_but_failures_and_the_end_always_show(monkeypatch):
    """In a log, a line at most every LOG_INTERVAL seconds, plus every failed run and the
    last run; on a terminal the bar is redrawn at most every TTY_INTERVAL seconds."""
    import io
    import patrolling_sim.campaign.engine as campaign_mod
    clock = {"t": 100.0}
    monkeypatch.setattr(campaign_mod.time, "monotonic", lambda: clock["t"])

    def rec(i, status="TIMEOUT"):
        return {"status": status, "config": {"map": "grid", "robots": 2, "alg": "CR",
                                             "seed": i}}

    out = io.StringIO()
    prog = campaign_mod._Progress(100, 0, out)
    for i in range(100):
        clock["t"] += 0.0625                   # a run every 1/16 s (exact in binary)
        prog.update(rec(i, "CRASHED" if i == 37 else "TIMEOUT"), 2)
    lines = out.getvalue().splitlines()
    # the first run; 2 s later (32 runs); the failed run; 2 s after it; the last run
    assert [line.split(" | ")[0].split("] ")[1] for line in lines] == [
        "1/100 done, 2 running, 0 failed, ETA 0m06s",
        "33/100 done, 2 running, 0 failed, ETA 0m04s",
        "38/100 done, 2 running, 1 failed, ETA 0m03s",
        "70/100 done, 2 running, 1 failed, ETA 0m01s",
        "100/100 done, 2 running, 1 failed, ETA 0m00s"], lines
    assert "seed 37 CRASHED" in lines[2] and "seed 99 TIMEOUT" in lines[-1]

    class Tty(io.StringIO):
        def isatty(self):
            return True
    out = Tty()
    prog = campaign_mod._Progress(100, 0, out)
    for i in range(100):
        clock["t"] += 0.0078125                # 1/128 s
        prog.update(rec(i), 1)
    draws = out.getvalue().split("\r")[1:]
    # 100/128 s: the first run, then every 13th (0.1 s = 12.8 runs), and the last
    assert [d.split(" done")[0].split("] ")[1] for d in draws] == [
        f"{k}/100" for k in (1, 14, 27, 40, 53, 66, 79, 92, 100)]


def test_worker_plugin_lets_group_signals_pass_but_not_to_the_programs_it_starts():
    """The worker plugin gives SIGINT and SIGTERM a handler that does nothing, not SIG_IGN:
    an ignored signal would be inherited by a ROS run the worker starts, a handled one is
    back to its default there."""
    from patrolling_sim.campaign.tasks import IgnoreGroupSignals
    sigs = (signal.SIGINT, signal.SIGTERM)
    old = {s: signal.getsignal(s) for s in sigs}
    try:
        IgnoreGroupSignals().setup()
        for s in sigs:
            h = signal.getsignal(s)
            assert callable(h) and h not in (signal.SIG_IGN, signal.SIG_DFL, old[s])
        os.kill(os.getpid(), signal.SIGTERM)       # handled: nothing happens
        child = subprocess.run(
            [sys.executable, "-c", "import signal; print(signal.getsignal(signal.SIGTERM) is "
             "signal.SIG_DFL, signal.getsignal(signal.SIGINT) is signal.default_int_handler)"],
            capture_output=True, text=True, timeout=60)
        assert child.stdout.split() == ["True", "True"], child.stdout + child.stderr
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def test_local_workers_drop_the_records_of_a_scheduler_gone_first():
    """After a Ctrl-C the campaign closes its cluster while a worker may still be busy with a
    run; that worker's late heartbeat then failed with a logged traceback of Dask's comm layer
    in the campaign's output. The worker plugin drops exactly those two records."""
    import logging
    from patrolling_sim.campaign.tasks import IgnoreGroupSignals, SchedulerGoneFirst
    log = logging.getLogger("distributed.worker")
    old_filters, old_int, old_term = list(log.filters), signal.getsignal(signal.SIGINT), \
        signal.getsignal(signal.SIGTERM)
    try:
        IgnoreGroupSignals().setup()
        IgnoreGroupSignals().setup()                  # a second setup adds no second filter
        assert sum(isinstance(f, SchedulerGoneFirst) for f in log.filters) == 1

        def passes(msg, *args):
            return log.filter(logging.LogRecord(log.name, logging.ERROR, __file__, 1, msg, args,
                                                None))
        assert not passes("Failed to communicate with scheduler during heartbeat.")
        assert not passes("Scheduler was unaware of this worker 'tcp://127.0.0.1:1'. "
                          "Shutting down.")
        assert passes("Compute Failed")
        assert passes("Worker stream died during communication: %s", "tcp://x")
    finally:
        log.filters[:] = old_filters
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)


def test_ros_campaign_runs_as_many_experiments_at_a_time_as_the_memory_holds():
    """ROS mode: half the cores by default, fewer when the largest run's memory estimate
    does not fit that many times; a --workers value is kept, with a warning."""
    from patrolling_sim.experiment import validation
    from patrolling_sim.campaign.cluster import ros_concurrency
    small = {"map": "grid", "robots": 2, "processes": "shared", "nav": "spqrel_nav_lite"}
    big = dict(small, map="broughton", robots=12)
    need = validation.memory_estimate_mb(12, "shared",
                                         *validation.map_memory_figures("broughton"))
    assert ros_concurrency([small], cores=16, available=64000.0) == (8, None)
    n, note = ros_concurrency([small, big], cores=16, available=3.5 * need)
    assert n == 3 and "largest run needs about" in note
    assert ros_concurrency([big], cores=2, available=0.5 * need)[0] == 1
    n, note = ros_concurrency([big], cores=16, requested=5, available=3.5 * need)
    assert n == 5 and note.startswith("warning: --workers 5:")
    assert ros_concurrency([big], cores=16, requested=3, available=3.5 * need) == (3, None)
    # the abstract world has no navigation to hold
    abstract = dict(big, nav="abstract")
    assert ros_concurrency([abstract], cores=16, available=3.5 * need) == (8, None)
