"""Reference tables (patrolling_sim.report.reference_docs, scripts/reference_docs.py) on a synthetic
campaign folder: the table's numbers equal pandas' mean and SD, partial campaigns and
excluded runs are labelled and counted, bad input fails in one line with exit 2 and writes
nothing."""
import os
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))

from patrolling_sim.report import reference_docs as rd  # noqa: E402
from patrolling_sim.common.errors import PatrolInputError  # noqa: E402

SCRIPT = os.path.join(ROOT, "scripts", "reference_docs.py")
METRIC_COLS = [c for c, _, _ in rd.METRICS]


def _runs(seeds=3):
    rng = np.random.default_rng(7)
    rows = []
    for m in ("grid", "1r5"):
        for n in (1, 2):
            for a in ("CR", "DTAG"):
                for s in range(seeds):
                    row = {"key": f"{m}{n}{a}{s}", "mode": "graph", "map": m, "robots": n,
                           "alg": a, "duration": 300, "seed": s, "speed": 1.0,
                           "status": "TIMEOUT"}
                    row.update({c: round(float(rng.uniform(5, 300)), 3) for c in METRIC_COLS})
                    rows.append(row)
    df = pd.DataFrame(rows)
    # grid_2 DTAG: seed 2 not run yet, seed 1 ended in FAIL (excluded, counted)
    sel = (df["map"] == "grid") & (df["robots"] == 2) & (df["alg"] == "DTAG")
    df.loc[sel & (df["seed"] == 2), "status"] = "NOT_RUN"
    df.loc[sel & (df["seed"] == 2), METRIC_COLS] = np.nan
    df.loc[sel & (df["seed"] == 1), "status"] = "FAIL"
    return df


def _write(tmp_path, df):
    d = tmp_path / "camp"
    d.mkdir()
    df.to_csv(d / "runs.csv", index=False)
    return str(d)


def _table_rows(md, robots):
    sec = md.split(f"## {robots} robot")[1].split("\n## ")[0]
    return {ln.split("|")[1].strip(): [c.strip() for c in ln.split("|")[2:-1]]
            for ln in sec.splitlines() if ln.startswith("| ") and not ln.startswith("| algo")}


def test_tables_match_pandas_and_partial_is_labelled(tmp_path):
    df = _runs()
    camp = _write(tmp_path, df)
    out = tmp_path / "ref"
    r = subprocess.run([sys.executable, SCRIPT, camp, "--out", str(out)], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(out)) == ["1r5.md", "1r5.png", "README.md", "grid.md", "grid.png"]
    index = (out / "README.md").read_text()
    assert f"scripts/reference_docs.py {camp} --out {out}" in index
    assert "PARTIAL: 22 of 24 runs done" in index and "1 excluded" in index
    ok = df[df["status"] == "TIMEOUT"]
    for m in ("grid", "1r5"):
        page = (out / f"{m}.md").read_text()
        assert "PARTIAL" in page
        assert (out / f"{m}.png").read_bytes()[:4] == b"\x89PNG"
        for n in (1, 2):
            rows = _table_rows(page, n)
            for a in ("CR", "DTAG"):
                g = ok[(ok["map"] == m) & (ok["robots"] == n) & (ok["alg"] == a)]
                cells = rows[a]
                short = len(g) < 3
                assert cells[0] == f"{len(g)}" + ("\\*" if short else "")
                assert cells[1] == ("1" if (m, n, a) == ("grid", 2, "DTAG") else "0")
                for (c, _, dec), cell in zip(rd.METRICS, cells[2:]):
                    mean = g[c].mean()
                    if len(g) > 1:
                        assert cell == f"{mean:.{dec}f} ± {g[c].std(ddof=1):.{dec}f}"
                    else:
                        assert cell == f"{mean:.{dec}f}"
            assert "*cyclic reference L/(k v)*" in rows and "*partition reference*" in rows
    # the grid's cyclic reference for 2 robots: half the 1-robot tour
    page = (out / "grid.md").read_text()
    L = float(re.search(r"Best closed tour L = ([\d.]+) m", page).group(1))
    assert _table_rows(page, 2)["*cyclic reference L/(k v)*"][2] == f"{L / 2:.1f}"


def test_complete_campaign_is_not_partial(tmp_path):
    docs = rd.build_reference_docs(_write(tmp_path, _runs(seeds=2)[lambda d: d["map"] == "grid"]
                                          .assign(status="TIMEOUT").fillna(1.0)), "cmd")
    assert not docs.partial and docs.done == docs.total == 8
    index = docs.files["README.md"]
    assert "PARTIAL" not in index and "complete: 8 of 8" in index


@pytest.mark.parametrize("case,msg", [
    ("nofolder", "no such campaign folder"),
    ("nocsv", "no runs.csv"),
    ("garbage", "malformed csv"),
    ("nocols", "missing column(s)"),
    ("badmap", "map 'nowhere'"),
    ("badmetric", "non-numeric value"),
    ("varies", "column speed varies"),
])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, case, msg):
    camp = str(tmp_path / "camp")
    if case != "nofolder":
        os.makedirs(camp)
    df = _runs()
    if case == "garbage":
        with open(os.path.join(camp, "runs.csv"), "w") as f:
            f.write('a,b\n1,"2\n')
    elif case == "nocols":
        df.drop(columns=["alg"]).to_csv(os.path.join(camp, "runs.csv"), index=False)
    elif case == "badmap":
        df.assign(map=df["map"].replace("1r5", "nowhere")).to_csv(
            os.path.join(camp, "runs.csv"), index=False)
    elif case == "badmetric":
        df["idl_avg"] = df["idl_avg"].astype(object)
        df.loc[0, "idl_avg"] = "abc"
        df.to_csv(os.path.join(camp, "runs.csv"), index=False)
    elif case == "varies":
        df.loc[0, "speed"] = 0.5
        df.to_csv(os.path.join(camp, "runs.csv"), index=False)
    out = tmp_path / "ref"
    r = subprocess.run([sys.executable, SCRIPT, camp, "--out", str(out)], capture_output=True,
                       text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and msg in r.stderr and "reference_docs.py: error:" in r.stderr
    assert not out.exists()
    with pytest.raises(PatrolInputError):
        rd.load_runs(camp)


def _starving_runs():
    """grid_2 DTAG leaves vertices unvisited in seeds 0 and 2 (1 and 3 vertices); 1r5_1 CR in
    seed 1; nothing else does."""
    df = _runs().assign(status="TIMEOUT", never_visited=0)
    df = df.fillna(10.0)
    sel = (df["map"] == "grid") & (df["robots"] == 2) & (df["alg"] == "DTAG")
    df.loc[sel & (df["seed"] == 0), "never_visited"] = 1
    df.loc[sel & (df["seed"] == 2), "never_visited"] = 3
    df.loc[(df["map"] == "1r5") & (df["robots"] == 1) & (df["alg"] == "CR")
           & (df["seed"] == 1), "never_visited"] = 2
    return df


def test_never_visited_cells_are_flagged_with_their_cause(tmp_path):
    causes = tmp_path / "causes.yaml"
    causes.write_text("- alg: DTAG\n  maps: [grid]\n  robots: all\n  cause: the test's cause.\n"
                      "  link: algorithms/DTAG.md#x\n- alg: DTAG\n  maps: all\n  robots: [1]\n"
                      "  cause: another.\n")
    docs = rd.build_reference_docs(_write(tmp_path, _starving_runs()), "cmd",
                                   causes_file=str(causes))
    grid = docs.files["grid.md"]
    row = _table_rows(grid, 2)["DTAG"]
    assert row[-1] == "2 of 3 (up to 3)"
    worst = [h for _, h, _ in rd.METRICS].index("worst idleness [s]")
    assert row[2 + worst].startswith("≥ ")
    assert all(c == "" for a, r in _table_rows(grid, 2).items() if a == "CR" for c in r[-1:])
    assert not any(r[2 + worst].startswith("≥") for r in _table_rows(grid, 1).values())
    assert ("**DTAG**: in 2 of 3 seeds some vertex was never visited in 300 s" in grid
            and "Cause: the test's cause. ([more](../algorithms/DTAG.md#x))" in grid)
    page = docs.files["1r5.md"]
    assert _table_rows(page, 1)["CR"][-1] == "1 of 3 (up to 2)"
    assert "**CR**: in 1 of 3 seeds" in page and "Cause: **not documented**." in page
    index = docs.files["README.md"]
    assert ("| grid | 2 | DTAG | never visited: 2 of 3 seeds, up to 3 vertices | "
            "[documented](../algorithms/DTAG.md#x) |") in index.replace("[grid](grid.md)", "grid")
    assert ("| 1 | CR | never visited: 1 of 3 seeds, up to 2 vertices | **not documented** |"
            in index)


@pytest.mark.parametrize("text,msg", [
    ("alg: DTAG\n", "expected a list of entries"),
    ("- alg: DTAG\n  maps: all\n  robots: all\n", "entry 1: missing key(s) cause"),
    ("- alg: DTAG\n  maps: all\n  robots: [0]\n  cause: x\n", "robots must be"),
    ("- alg: DTAG\n  maps: grid\n  robots: all\n  cause: x\n", "maps must be"),
    ("- alg: DTAG\n  maps: all\n  robots: all\n  cause: x\n  why: y\n", "unknown key(s) why"),
    ("- [\n", "bad YAML"),
])
def test_bad_causes_file_is_one_line_naming_it(tmp_path, text, msg):
    causes = tmp_path / "causes.yaml"
    causes.write_text(text)
    with pytest.raises(PatrolInputError) as e:
        rd.build_reference_docs(_write(tmp_path, _starving_runs()), "cmd",
                                causes_file=str(causes))
    assert "\n" not in str(e.value) and msg in str(e.value) and str(causes) in str(e.value)


def test_bad_causes_file_exit_2_nothing_written(tmp_path):
    camp = _write(tmp_path, _starving_runs())
    out = tmp_path / "ref"
    r = subprocess.run([sys.executable, SCRIPT, camp, "--out", str(out), "--causes",
                        str(tmp_path / "missing.yaml")], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "missing.yaml: cannot read causes file" in r.stderr
    assert not out.exists()


def test_shipped_causes_file_loads():
    assert rd.starvation.load_causes(os.path.join(ROOT, "campaigns", "reference_causes.yaml"))


def test_a_worst_idleness_that_rises_with_the_team_is_flagged(tmp_path):
    df = _starving_runs().assign(never_visited=0)
    for n, w in ((1, 100.0), (2, 160.0)):            # 1r5 CR: 1.6x with 2 robots
        df.loc[(df["map"] == "1r5") & (df["alg"] == "CR") & (df["robots"] == n),
               "worst_idleness"] = w
    for n, w in ((1, 100.0), (2, 140.0)):            # grid CR: 1.4x, under the 1.5 factor
        df.loc[(df["map"] == "grid") & (df["alg"] == "CR") & (df["robots"] == n),
               "worst_idleness"] = w
    causes = tmp_path / "causes.yaml"
    causes.write_text("- alg: CR\n  maps: [1r5]\n  robots: [2]\n  cause: the rise's cause.\n")
    docs = rd.build_reference_docs(_write(tmp_path, df), "cmd", causes_file=str(causes))
    worst = [h for _, h, _ in rd.METRICS].index("worst idleness [s]")
    page = docs.files["1r5.md"]
    assert _table_rows(page, 2)["CR"][2 + worst].startswith("↑ 160.0")
    assert not _table_rows(page, 1)["CR"][2 + worst].startswith("↑")
    assert ("**CR** (↑): its worst idleness, 160 s, is 1.6 times that of 1 robot on this map "
            "(100 s). Cause: the rise's cause." in page)
    assert not _table_rows(docs.files["grid.md"], 2)["CR"][2 + worst].startswith("↑")
    index = docs.files["README.md"]
    assert "1 cells are flagged (0 without a documented cause)" in index
    assert "↑ worst idleness 1.6x that of 1 robot |" in index
