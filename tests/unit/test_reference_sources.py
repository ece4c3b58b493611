"""Reference tables built from several campaigns (``--replace``) and linked to the fidelity
matrix (``--fidelity``): a replaced algorithm's figures come only from the replacing
campaign, the others' only from the base; grids or settings that do not match, an algorithm
replaced twice and bad status files fail in one line."""
import os
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))
sys.path.insert(0, os.path.dirname(__file__))

from patrolling_sim.common.errors import PatrolInputError  # noqa: E402
from patrolling_sim.report import fidelity_status  # noqa: E402
from patrolling_sim.report import reference_docs as rd  # noqa: E402
from patrolling_sim.report import reference_relink as rl  # noqa: E402
from test_reference_docs import _runs, _table_rows  # noqa: E402


def _folder(tmp_path, name, df, commit):
    d = tmp_path / name
    d.mkdir()
    df.to_csv(d / "runs.csv", index=False)
    (d / "provenance.yaml").write_text(f"name: {name}\ncode:\n  commit: {commit}\n"
                                       "  dirty: false\n")
    return str(d)


def _pair(tmp_path):
    base = _runs().assign(status="TIMEOUT")
    new = base[base["alg"] == "DTAG"].copy()
    new["idl_avg"] = 1000.0 + new["seed"]               # unmistakable figures
    return (_folder(tmp_path, "base", base, "a" * 40), _folder(tmp_path, "redo", new, "b" * 40),
            base)


def test_replaced_algorithm_comes_from_the_replacing_campaign_only(tmp_path):
    base, redo, df = _pair(tmp_path)
    docs = rd.build_reference_docs(base, "cmd", replace=[redo])
    rows = _table_rows(docs.files["grid.md"], 1)
    assert rows["DTAG"][2].startswith("1001.0 ± 1.0")           # mean of 1000, 1001, 1002
    cr = df[(df["map"] == "grid") & (df["robots"] == 1) & (df["alg"] == "CR")]["idl_avg"]
    assert rows["CR"][2].startswith(f"{cr.mean():.1f}")
    assert docs.total == len(df)                                  # no run counted twice
    index = docs.files["README.md"]
    assert "`redo` (file" in index and "bbbbbbbbbbbb" in index and ": DTAG" in index
    assert "aaaaaaaaaaaa" in index and ": CR" in index


@pytest.mark.parametrize("case,msg", [
    ("grid", "not the same maps, team sizes and seeds"),
    ("setting", "setting duration of DTAG differs"),
    ("unknown", "the runs of XX are not the same maps, team sizes and seeds"),
    ("twice", "already replaced by"),
])
def test_mismatched_replacement_is_one_line_error(tmp_path, case, msg):
    base, redo, df = _pair(tmp_path)
    new = df[df["alg"] == "DTAG"].copy()
    folders = [redo]
    if case == "grid":
        new = new[new["seed"] != 0]
    elif case == "setting":
        new["duration"] = 600
    elif case == "unknown":                  # an added algorithm must cover the whole grid
        new = new[new["map"] == "grid"].assign(alg="XX")
    if case == "twice":
        folders.append(_folder(tmp_path, "again", new, "c" * 40))
    else:
        folders = [_folder(tmp_path, "bad", new, "c" * 40)]
    with pytest.raises(PatrolInputError, match=msg) as e:
        rd.build_reference_docs(base, "cmd", replace=folders)
    assert "\n" not in str(e.value)


def test_fidelity_column_links_measured_cells(tmp_path):
    base, _, _ = _pair(tmp_path)
    status = tmp_path / "status.csv"
    fidelity_status.write_status(str(status), [("grid", 2, "DTAG", "known", "-16% / -94%"),
                                               ("1r5", 1, "CR", "within", "+1% / +2% / +0%")])
    docs = rd.build_reference_docs(base, "cmd", fidelity_file=str(status))
    assert _table_rows(docs.files["grid.md"], 2)["DTAG"][-1] == "[known](../fidelity_matrix.md)"
    assert _table_rows(docs.files["grid.md"], 2)["CR"][-1] == ""
    assert _table_rows(docs.files["1r5.md"], 1)["CR"][-1] == "[within](../fidelity_matrix.md)"
    assert "vs original" not in rd.build_reference_docs(base, "cmd").files["grid.md"]


@pytest.mark.parametrize("text,msg", [
    ("map,robots,alg,status\n", "missing column(s) detail"),
    ("map,robots,alg,status,detail\ngrid,two,CR,within,\n", "line 2: robots must be"),
    ("map,robots,alg,status,detail\ngrid,2,CR,fine,\n", "line 2: status must be one of"),
    ("map,robots,alg,status,detail\ngrid,2,CR,within,\ngrid,2,CR,known,\n", "given twice"),
])
def test_bad_status_file_is_one_line_error(tmp_path, text, msg):
    p = tmp_path / "s.csv"
    p.write_text(text)
    with pytest.raises(PatrolInputError, match=msg.replace("(", r"\(").replace(")", r"\)")):
        fidelity_status.load_status(str(p))


def test_added_algorithm_covers_the_whole_grid_and_keeps_its_label(tmp_path):
    base = _runs().assign(status="TIMEOUT")
    one = base[base["alg"] == "CR"].assign(alg="POLICY", idl_avg=7.0)
    one["prefix"] = [f"r{i}" for i in range(len(one))]
    folder = _folder(tmp_path, "learned", one, "d" * 40)
    for p in one["prefix"]:                    # the monitor's info.csv: the policy's label
        (tmp_path / "learned" / f"{p}_info.csv").write_text(
            "grid;1;default;0.0;0.00;graph;POLICY;mine@0123abcd;vm;20260101_000000;300.0;"
            "1.0;1;TIMEOUT;0.5;7.0;1.0;20.0;0.1;100;10.0;5\n")
    docs = rd.build_reference_docs(_folder(tmp_path, "base", base, "a" * 40), "cmd",
                                   replace=[folder])
    rows = _table_rows(docs.files["grid.md"], 1)
    assert rows["POLICY mine@0123abcd"][2].startswith("7.0") and "CR" in rows
    assert docs.total == len(base) + len(one)


def test_relink_gives_the_pages_a_new_status_file_would(tmp_path):
    """Relinking pages made with an old status file to a new one gives, page for page, what
    building them with the new file gives (the index only says it was relinked); a page
    without the column, a folder without pages and a bad status file are one-line errors and
    write nothing."""
    base, _, _ = _pair(tmp_path)
    old, new = tmp_path / "old.csv", tmp_path / "new.csv"
    fidelity_status.write_status(str(old), [("grid", 2, "DTAG", "known", "-16% / -94%")])
    fidelity_status.write_status(str(new), [("grid", 2, "DTAG", "within", "-1% / -4%"),
                                            ("grid", 1, "CR", "differs", "+30% / +2% / +0%")])
    out = tmp_path / "pages"
    rd.write_docs(rd.build_reference_docs(base, "cmd", fidelity_file=str(old)), str(out))
    rd.relink_docs(str(out), str(new))
    fresh = rd.build_reference_docs(base, "cmd", fidelity_file=str(new))
    for name, content in fresh.files.items():
        if name.endswith(".md") and name != "README.md":
            got = (out / name).read_text()
            # the generation line names the date of each build; the tables must agree
            assert got.split("\n")[3:] == content.split("\n")[3:], name
    assert _table_rows((out / "grid.md").read_text(), 1)["CR"][-1] == \
        "[differs](../fidelity_matrix.md)"
    assert (out / "README.md").read_text().count(rl.RELINK_MARK) == 1
    rd.relink_docs(str(out), str(new))                       # again: still one such line
    assert (out / "README.md").read_text().count(rl.RELINK_MARK) == 1

    plain = tmp_path / "plain"
    rd.write_docs(rd.build_reference_docs(base, "cmd"), str(plain))
    before = {p.name: p.read_bytes() for p in plain.iterdir()}
    for folder, status, msg in ((plain, new, "no column 'vs original'"),
                                (tmp_path / "none", new, "no reference tables here"),
                                (out, tmp_path / "missing.csv", "cannot read")):
        with pytest.raises(PatrolInputError, match=msg) as e:
            rd.relink_docs(str(folder), str(status))
        assert "\n" not in str(e.value)
    assert {p.name: p.read_bytes() for p in plain.iterdir()} == before
