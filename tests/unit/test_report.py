"""scripts/report.py on synthetic result sets written in the original monitor's formats.

The expected numbers are recomputed here from the idleness.csv / info.csv files with the
csv module and the statistics module only (not with the report code).
"""
import csv
import math
import os
import random
import shutil
import statistics
import subprocess
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
REPORT = os.path.join(ROOT, "scripts", "report.py")
GRAPH_SIM = os.path.join(ROOT, "scripts", "graph_sim.py")
# files written by the original monitor, copied into the repository (see the README there)
ORIGINAL = os.path.join(ROOT, "tests", "unit", "data", "original_output_example")


def write_run(root, map_name, n, alg, host, stamp, rng, n_vertices, level, duration=600.0,
              nav="graph", cycles=None, info=True):
    """Write one run's four files; idleness samples ~ level * U(0.5, 1.5)."""
    folder = os.path.join(root, f"{map_name}_{n}", alg, host)
    os.makedirs(folder, exist_ok=True)
    prefix = os.path.join(folder, stamp)
    rows, t, interf = [], 20.0, 0
    for _ in range(rng.randint(60, 120)):
        t += rng.uniform(0.5, 5.0)
        if rng.random() < 0.05:
            interf += 1
        rows.append((t, rng.randrange(n), rng.randrange(n_vertices),
                     level * rng.uniform(0.5, 1.5), interf))
    with open(prefix + "_idleness.csv", "w") as f:
        f.write("Time;Robot;Node;Idleness;Interferences\n")
        for r in rows:
            f.write("%.1f;%d;%d;%.1f;%d\n" % r)
    with open(prefix + "_timeresults.csv", "w") as f:
        f.write("Time;Idleness min;Idleness avg;Idleness stddev;Idleness max;Interferences\n")
    with open(prefix + "_results.txt", "w") as f:
        f.write("\nComplete Patrol Cycles:\t1\n\n")
    vals = [round(r[3], 1) for r in rows]
    avg = sum(vals) / len(vals)
    sd = math.sqrt(sum((v - avg) ** 2 for v in vals) / len(vals))
    cyc = cycles if cycles is not None else rng.randint(2, 9)
    if info:
        fields = [map_name, str(n), "default", "0.0", "0.00", nav, alg, "", host, stamp,
                  "%.1f" % duration, "%.1f" % (duration / 50), str(interf), "TIMEOUT",
                  "%.1f" % min(vals), "%.1f" % avg, "%.1f" % sd, "%.1f" % max(vals),
                  "%.2f" % (interf / duration * 60), str(len(vals) + n_vertices),
                  "%.1f" % ((len(vals) + n_vertices) / n_vertices), str(cyc)]
        with open(prefix + "_info.csv", "w") as f:
            f.write(";".join(fields) + "\n")
    return prefix


def run_report(args, **kw):
    return subprocess.run([sys.executable, REPORT, *args], capture_output=True, text=True,
                          timeout=120, **kw)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def recompute(results_root):
    """{(map, N, alg): dict(runs, avg, avg_sd, max, max_sd, cyc, cyc_sd, ir, ir_sd)} from the
    files alone."""
    per = {}
    for dirpath, _, files in os.walk(results_root):
        for name in files:
            if not name.endswith("_info.csv"):
                continue
            with open(os.path.join(dirpath, name)) as f:
                info = f.read().strip().split(";")
            idl = []
            with open(os.path.join(dirpath, name[:-9] + "_idleness.csv"), newline="") as f:
                for row in csv.DictReader(f, delimiter=";"):
                    idl.append(float(row["Idleness"]))
            key = (info[0], int(info[1]), info[6])
            per.setdefault(key, []).append((statistics.mean(idl), max(idl), int(info[21]),
                                            float(info[18])))
    out = {}
    for key, runs in per.items():
        cols = list(zip(*runs))
        sd = (lambda v: statistics.stdev(v) if len(v) > 1 else None)
        out[key] = dict(runs=len(runs),
                        avg=statistics.mean(cols[0]), avg_sd=sd(cols[0]),
                        max=statistics.mean(cols[1]), max_sd=sd(cols[1]),
                        cyc=statistics.mean(cols[2]), cyc_sd=sd(cols[2]),
                        ir=statistics.mean(cols[3]), ir_sd=sd(cols[3]))
    return out


def check_summary(summary_csv, expected):
    rows = read_csv(summary_csv)
    assert len(rows) == len(expected)
    names = {"avg": "avg_idleness", "max": "max_idleness", "cyc": "complete_cycles",
             "ir": "interference_rate"}
    for row in rows:
        key = (row["map"], int(row["N"]), row["algorithm"])
        exp = expected[key]
        assert int(row["runs"]) == exp["runs"], key
        for short, col in names.items():
            assert float(row[col + "_mean"]) == pytest.approx(exp[short], rel=1e-5,
                                                              abs=1e-4), (key, col)
            if exp[short + "_sd"] is None:
                assert row[col + "_sd"] == "", (key, col)
            else:
                assert float(row[col + "_sd"]) == pytest.approx(exp[short + "_sd"], rel=1e-5,
                                                                abs=1e-4), (key, col)


def check_outputs(out, n_runs):
    for f in ("report.html", "summary.csv", "runs.csv", "pairwise_pvalues.csv"):
        assert os.path.getsize(os.path.join(out, f)) > 0, f
    pngs = [f for f in os.listdir(out) if f.endswith(".png")]
    for kind in ("boxplot_", "heatmap_", "histogram_"):
        assert any(p.startswith(kind) for p in pngs), (kind, pngs)
    times = [f for f in os.listdir(os.path.join(out, "runs")) if f.endswith(".png")]
    assert len(times) == n_runs
    for p in pngs + [os.path.join("runs", t) for t in times]:
        with open(os.path.join(out, p), "rb") as f:
            assert f.read(8) == b"\x89PNG\r\n\x1a\n", p
    with open(os.path.join(out, "report.html"), encoding="utf-8") as f:
        page = f.read()
    # self-contained: every figure embedded, no external image reference
    assert page.count("data:image/png;base64,") == len(pngs) + n_runs
    assert "<img" in page and 'src="' + "http" not in page
    return page


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """grid N=2: CR (4 runs, low idleness), RAND (4 runs, high), HCR (4 runs, middle);
    example N=1: CR and HCR with 1 run each; plus one unfinished run (no info.csv)."""
    root = str(tmp_path_factory.mktemp("results"))
    rng = random.Random(7)
    k = 0
    for alg, level in (("CR", 20.0), ("RAND", 80.0), ("HCR", 45.0)):
        for s in range(4):
            k += 1
            write_run(root, "grid", 2, alg, "hostA", f"20260101_1000{k:02d}", rng, 25,
                      level + s)
    write_run(root, "example", 1, "CR", "hostB", "20260102_120000", rng, 29, 60.0, nav="ros")
    write_run(root, "example", 1, "HCR", "hostB", "20260102_130000", rng, 29, 70.0, nav="ros")
    write_run(root, "example", 1, "HCR", "hostB", "20260102_140000", rng, 29, 70.0,
              nav="ros", info=False)
    out = str(tmp_path_factory.mktemp("report"))
    proc = run_report([root, "--out", out, "--title", "synthetic"])
    return root, out, proc


def test_synthetic_files_and_table(synthetic):
    root, out, proc = synthetic
    assert proc.returncode == 0, proc.stderr
    page = check_outputs(out, 14)
    assert "synthetic" in page
    check_summary(os.path.join(out, "summary.csv"), recompute(root))
    # the unfinished run is reported in one warning line and skipped
    warn = [l for l in proc.stderr.splitlines() if "20260102_140000_idleness.csv" in l]
    assert len(warn) == 1 and "skipped" in warn[0]


def test_synthetic_significance(synthetic):
    root, out, proc = synthetic
    assert proc.returncode == 0, proc.stderr
    rows = read_csv(os.path.join(out, "pairwise_pvalues.csv"))
    grid = [r for r in rows if r["map"] == "grid"]
    ex = [r for r in rows if r["map"] == "example"]
    assert len(grid) == 3 and len(ex) == 1
    assert {r["basis"] for r in grid} == {"run means"}
    assert ex[0]["basis"] == "samples"
    # grid: the three algorithms' run means do not overlap, so every pair is completely
    # separated: exact two-sided Mann-Whitney p = 2 / C(8, 4); Holm over 3 equal p-values
    p_sep = 2 / math.comb(8, 4)
    for r in grid:
        assert int(r["n_a"]) == 4 and int(r["n_b"]) == 4
        assert float(r["p_raw"]) == pytest.approx(p_sep, rel=1e-6)
        assert float(r["p_holm"]) == pytest.approx(min(1.0, 3 * p_sep), rel=1e-6)
        assert float(r["kruskal_p"]) < 0.05
    # example: one run each -> samples basis, sample counts from the files
    counts = {}
    for dirpath, _, files in os.walk(os.path.join(root, "example_1")):
        for name in files:
            if name.endswith("_idleness.csv") and os.path.exists(
                    os.path.join(dirpath, name[:-13] + "_info.csv")):
                with open(os.path.join(dirpath, name)) as f:
                    counts[dirpath.split(os.sep)[-2]] = sum(1 for _ in f) - 1
    assert int(ex[0]["n_a"]) == counts[ex[0]["algorithm_a"]]
    assert int(ex[0]["n_b"]) == counts[ex[0]["algorithm_b"]]


def test_single_original_run(tmp_path):
    """The original monitor's real output: one run, sd n/a, no significance rows."""
    assert os.path.isdir(ORIGINAL), f"{ORIGINAL} missing from the repository"
    out = str(tmp_path / "rep")
    proc = run_report([ORIGINAL, "--out", out])
    assert proc.returncode == 0, proc.stderr
    page = check_outputs(out, 1)
    rows = read_csv(os.path.join(out, "summary.csv"))
    assert len(rows) == 1 and rows[0]["runs"] == "1" and rows[0]["avg_idleness_sd"] == ""
    check_summary(os.path.join(out, "summary.csv"), recompute(ORIGINAL))
    assert len(read_csv(os.path.join(out, "pairwise_pvalues.csv"))) == 0
    assert "± n/a" in page
    # the original writes info.csv's averages at the last cycle: reported, samples used
    assert "differs from the mean of the idleness samples" in proc.stderr


def test_single_synthetic_run(tmp_path):
    """One run on a shipped map whose info.csv average differs from its samples (as the
    original writes it at the last cycle): every file, sd empty, no tests, one warning."""
    root = str(tmp_path / "r")
    prefix = write_run(root, "example", 3, "DTAP", "h", "20260101_000000",
                       random.Random(5), 29, 40.0)
    with open(prefix + "_info.csv") as f:
        fields = f.read().strip().split(";")
    fields[15] = "%.1f" % (float(fields[15]) + 3.0)
    with open(prefix + "_info.csv", "w") as f:
        f.write(";".join(fields) + "\n")
    out = str(tmp_path / "o")
    proc = run_report([root, "--out", out])
    assert proc.returncode == 0, proc.stderr
    page = check_outputs(out, 1)
    check_summary(os.path.join(out, "summary.csv"), recompute(root))
    assert read_csv(os.path.join(out, "summary.csv"))[0]["avg_idleness_sd"] == ""
    assert read_csv(os.path.join(out, "pairwise_pvalues.csv")) == []
    assert read_csv(os.path.join(out, "runs.csv"))[0]["idl_avg_agrees"] == "False"
    warn = [l for l in proc.stderr.splitlines() if "differs from the mean" in l]
    assert len(warn) == 1 and prefix + "_info.csv" in warn[0]
    assert "± n/a" in page and "No comparison" in page


def test_graph_mode_results(tmp_path):
    """A results set generated by graph mode: three algorithms, two seeds each."""
    res = tmp_path / "res"
    algs = ("CR", "HCR", "RAND")
    for alg in algs:
        for seed in (1, 2):
            p = subprocess.run([sys.executable, GRAPH_SIM, "--map", "grid", "--robots", "2",
                                "--alg", alg, "--duration", "600", "--seed", str(seed),
                                "--results-dir", str(res)],
                               capture_output=True, text=True, timeout=120)
            assert p.returncode == 0, p.stderr
    out = str(tmp_path / "rep")
    proc = run_report([str(res), "--out", out])
    assert proc.returncode == 0, proc.stderr
    check_outputs(out, 6)
    expected = recompute(str(res))
    assert sorted(expected) == [("grid", 2, a) for a in algs]
    check_summary(os.path.join(out, "summary.csv"), expected)
    runs = read_csv(os.path.join(out, "runs.csv"))
    assert {r["nav_module"] for r in runs} == {"graph"}
    # graph mode writes info.csv's average from the same samples
    assert all(r["idl_avg_agrees"] == "True" for r in runs), runs
    pv = read_csv(os.path.join(out, "pairwise_pvalues.csv"))
    assert len(pv) == 3 and {r["basis"] for r in pv} == {"run means"}


def test_holm_and_bins():
    from patrolling_sim.report.stats import holm
    from patrolling_sim.report.plots import histogram_bins
    # hand-computed: sorted 0.01, 0.02, 0.04 -> 0.03, 0.04, 0.04 (monotone)
    assert list(holm([0.04, 0.01, 0.02])) == pytest.approx([0.04, 0.03, 0.04])
    assert list(holm([0.5, 0.6])) == pytest.approx([1.0, 1.0])
    # Freedman-Diaconis 2*IQR/n^(1/3) rounded up to 1/2/5 x 10^k, at least 1 s:
    # IQR 2, n 5 -> 2.34 -> 5;  IQR 20, n 1000 -> 4 -> 5;  IQR 1, n 1000 -> 0.2 -> 1
    edges, width = histogram_bins([0.0, 1.0, 2.0, 3.0, 4.0])
    assert width == 5.0 and edges[0] == 0.0 and edges[-1] >= 4.0
    assert histogram_bins([float(i % 41) for i in range(1000)])[1] == 5.0
    assert histogram_bins([10 + (i % 3) for i in range(1000)])[1] == 1.0
    # never more than 300 bins: one huge outlier among tight samples
    edges, width = histogram_bins([1.0] * 100 + [1e5])
    assert len(edges) <= 302 and width >= 1e5 / 300


# --- bad input -----------------------------------------------------------------------

def _one_line_error(proc, *needles):
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("report.py: error: ")
    for n in needles:
        assert n in lines[0], (n, lines[0])


def test_missing_path(tmp_path):
    missing = str(tmp_path / "nope")
    _one_line_error(run_report([missing, "--out", str(tmp_path / "o")]), missing,
                    "does not exist")


def test_no_results(tmp_path):
    (tmp_path / "empty" / "sub").mkdir(parents=True)
    (tmp_path / "empty" / "sub" / "notes.txt").write_text("x")
    _one_line_error(run_report([str(tmp_path / "empty"), "--out", str(tmp_path / "o")]),
                    "holds no results")


def test_missing_out_argument(tmp_path):
    _one_line_error(run_report([str(tmp_path)]), "--out")


@pytest.mark.parametrize("mutate,needle", [
    (lambda f: f[:-1], "21 ';'-separated fields, expected 22"),
    (lambda f: f[:1] + ["two"] + f[2:], "field 2 (team_size) is 'two'"),
    (lambda f: f[:15] + ["x"] + f[16:], "field 16 (idl_avg) is 'x'"),
    (lambda f: [], "empty info file"),
])
def test_malformed_info(tmp_path, mutate, needle):
    root = str(tmp_path / "r")
    prefix = write_run(root, "grid", 1, "CR", "h", "20260101_000000", random.Random(1), 25, 30)
    with open(prefix + "_info.csv") as f:
        fields = f.read().strip().split(";")
    with open(prefix + "_info.csv", "w") as f:
        f.write(";".join(mutate(fields)) + "\n")
    _one_line_error(run_report([root, "--out", str(tmp_path / "o")]),
                    prefix + "_info.csv", needle)


def test_malformed_idleness(tmp_path):
    root = str(tmp_path / "r")
    prefix = write_run(root, "grid", 1, "CR", "h", "20260101_000000", random.Random(1), 25, 30)
    with open(prefix + "_idleness.csv", "a") as f:
        f.write("99.0;0;3;abc;0\n")
    _one_line_error(run_report([root, "--out", str(tmp_path / "o")]),
                    prefix + "_idleness.csv", "Idleness", "abc")
    shutil.rmtree(root)
    prefix = write_run(root, "grid", 1, "CR", "h", "20260101_000000", random.Random(1), 25, 30)
    os.remove(prefix + "_idleness.csv")
    _one_line_error(run_report([root, "--out", str(tmp_path / "o")]),
                    prefix + "_idleness.csv", "not found")


def test_unknown_map_still_reports(tmp_path):
    """A map that is not shipped: no heat map (one warning), everything else produced."""
    root = str(tmp_path / "r")
    write_run(root, "nosuchmap", 1, "CR", "h", "20260101_000000", random.Random(2), 10, 30)
    out = str(tmp_path / "o")
    proc = run_report([root, "--out", out, "--no-run-plots"])
    assert proc.returncode == 0, proc.stderr
    assert "nosuchmap" in proc.stderr and "no heat map" in proc.stderr
    assert not [f for f in os.listdir(out) if f.startswith("heatmap_")]
    assert os.path.exists(os.path.join(out, "report.html"))
    assert not os.path.exists(os.path.join(out, "runs"))   # --no-run-plots


def test_extended_metrics_from_the_visit_log_or_the_campaign_file(tmp_path):
    """A run's time-averaged and worst idleness: from its visit log (computed at load, the log
    then dropped), or from the <prefix>_metrics.yaml a campaign wrote beside it."""
    sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
    from patrolling_sim.monitor.metrics import compute_metrics, read_visits
    from patrolling_sim.model.map_bundle import vertex_count
    from patrolling_sim.report.loading import load_run
    from patrolling_sim.report.result_sets import find_result_sets
    res = tmp_path / "res"
    p = subprocess.run([sys.executable, GRAPH_SIM, "--map", "grid", "--robots", "2", "--alg",
                        "CR", "--duration", "600", "--seed", "1", "--results-dir", str(res)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    (prefix,) = find_result_sets([str(res)]).prefixes
    run = load_run(prefix)
    info = run.info
    m = compute_metrics(read_visits(prefix + "_visits.csv"), vertex_count("grid"),
                        float(info["sim_duration"]))
    assert run.extended == (m.time_avg_idleness, m.worst_idleness)
    assert run.visits is None                  # no scenario: the log is not kept
    with open(prefix + "_metrics.yaml", "w") as f:
        f.write("time_avg_idleness: 12.5\nworst_idleness: 99.0\n")
    assert load_run(prefix).extended == (12.5, 99.0)
    out = str(tmp_path / "rep")
    proc = run_report([str(res), "--out", out, "--no-run-plots"])
    assert proc.returncode == 0, proc.stderr
    (row,) = read_csv(os.path.join(out, "runs.csv"))
    assert float(row["time_avg_idleness"]) == 12.5 and float(row["worst_idleness"]) == 99.0


@pytest.mark.parametrize("line, needle", [("99.0;0;3;-4.0;0", "negative"),
                                          ("99.0;0;3.5;4.0;0", "integer"),
                                          ("99.0;0;3;4.0", "Interferences"),
                                          ("99.0;0;3;inf;0", "Idleness")])
def test_idleness_fast_parse_falls_back_to_the_checked_one(tmp_path, line, needle):
    sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
    from patrolling_sim.common.errors import PatrolInputError
    from patrolling_sim.report import loading
    prefix = write_run(str(tmp_path), "grid", 2, "CR", "h", "20260101_000000",
                       random.Random(3), 25, 30)
    path = prefix + "_idleness.csv"
    fast = loading._read_idleness_numeric(path)
    assert fast is not None and fast.equals(loading.read_idleness(path))
    assert list(fast.dtypes.astype(str)) == ["float64", "int64", "int64", "float64", "int64"]
    with open(path, "a") as f:
        f.write(line + "\n")
    assert loading._read_idleness_numeric(path) is None
    with pytest.raises(PatrolInputError, match=needle):
        loading.read_idleness(path)


def test_without_run_plots_the_tables_are_the_same(synthetic, tmp_path):
    """--no-run-plots loads only the samples' Node and Idleness columns: every table
    (summary, runs, p-values, excluded runs) is the same as the full report's."""
    root, out, proc = synthetic
    assert proc.returncode == 0, proc.stderr
    slim = str(tmp_path / "slim")
    p = run_report([root, "--out", slim, "--title", "synthetic", "--no-run-plots"])
    assert p.returncode == 0, p.stderr
    for name in ("summary.csv", "runs.csv", "pairwise_pvalues.csv", "excluded.csv"):
        assert open(os.path.join(slim, name)).read() == open(os.path.join(out, name)).read()
    assert not os.path.isdir(os.path.join(slim, "runs")) or not os.listdir(
        os.path.join(slim, "runs"))


def test_longest_silence_column_and_warning(tmp_path):
    """A run record's longest_silence: the per-run table has the longest and its robot; a run
    whose robot was silent for more than half its dead_robot_timeout (_config.yaml) but not
    for all of it gets one warning naming it; a run without a record shows n/a."""
    root = str(tmp_path / "r")
    rng = random.Random(3)
    quiet = write_run(root, "grid", 3, "CR", "h", "20260101_000001", rng, 25, 30.0)
    frozen = write_run(root, "grid", 3, "CR", "h", "20260101_000002", rng, 25, 30.0)
    old = write_run(root, "grid", 3, "CR", "h", "20260101_000003", rng, 25, 30.0)
    for prefix, silences in ((quiet, [20.0, 31.5, 12.0]), (frozen, [20.0, 180.4, 30.0])):
        with open(prefix + "_run.yaml", "w") as f:
            f.write("status: TIMEOUT\nlongest_silence: [%s]\n" % ", ".join(map(str, silences)))
        with open(prefix + "_config.yaml", "w") as f:
            f.write("dead_robot_timeout: 300\n")
    out = str(tmp_path / "o")
    proc = run_report([root, "--out", out])
    assert proc.returncode == 0, proc.stderr
    runs = {r["prefix"]: r for r in read_csv(os.path.join(out, "runs.csv"))}
    assert float(runs[quiet]["longest_silence"]) == 31.5
    assert runs[quiet]["longest_silence_robot"] == "1"
    assert float(runs[frozen]["longest_silence"]) == 180.4
    assert runs[old]["longest_silence"] == "" and runs[old]["longest_silence_robot"] == "-1"
    warn = [l for l in proc.stderr.splitlines() if "without a visit report" in l]
    assert len(warn) == 1 and frozen in warn[0] and "robot 1 180 s" in warn[0], proc.stderr
    with open(os.path.join(out, "report.html"), encoding="utf-8") as f:
        page = f.read()
    assert "180.4 (robot 1)" in page and "longest silence (s)" in page
