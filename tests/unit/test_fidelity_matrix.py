"""Graph mode against the fidelity matrix: the stored runs of the original's own agents on
several maps and team sizes (tests/unit/data/original_matrix/, README there;
docs/fidelity_matrix.md).

For every stored cell (map, team size, algorithm), the mean of our graph mode over a few
seeds in the same world (default start positions, straight-line travel at 1 m/s, no
interference, goal wait 0, the runs' duration) must lie within the tolerances of
``original_matrix.TOL`` of the mean of the original's runs, or the difference must be listed,
with its reason, in ``known_differences.csv``. A difference listed for one metric of one
cell that has vanished fails too, so the list stays true. A cell whose every metric is
listed has nothing left to compare and is not simulated (its start vertices are still
checked). Runs in which an agent's process ended early (the original's crash) are left out.
"""
import pytest

import original_matrix as om

ROWS = om.read_rows()
CELLS = om.cells(ROWS)
KNOWN = om.known_differences()


def test_the_matrix_has_runs_of_the_original():
    assert len(CELLS) >= 8
    assert all(len(runs) >= 2 for runs in CELLS.values())
    assert {k[0] for k in CELLS} >= {"1r5", "grid"}


def test_every_row_is_a_usable_run():
    """Every stored run of the original lasted its whole duration (the monitor's timeout),
    and its visits per vertex add up to at least its visit count (the first visit of a
    vertex is a report but not an idleness sample)."""
    for r in ROWS:
        assert om.complete(r), (r["map"], r["robots"], r["algorithm"], r["run"])
        assert sum(r["visit_counts"]) >= r["visits"] and len(r["start_vertices"]) == r["robots"]


def test_known_differences_name_stored_cells_and_give_a_reason():
    stored = {(m, str(n), a) for m, n, a, _ in CELLS}
    for (m, n, a, metric), reason in KNOWN.items():
        assert (m, n, a) in stored or "*" in (m, n), (m, n, a)
        assert metric in om.METRICS + ("*",) and len(reason) > 20


def test_a_reason_split_by_a_quote_is_an_error(tmp_path):
    bad = tmp_path / "known.csv"
    bad.write_text('map,robots,algorithm,metric,reason\n'
                   'grid,4,CR,max,"see ("a section"), then more"\n', encoding="utf-8")
    with pytest.raises(ValueError, match="known.csv:2"):
        om.known_differences(str(bad))
    good = tmp_path / "good.csv"
    good.write_text('map,robots,algorithm,metric,reason\n'
                    'grid,4,CR,max,"see (""a section""), then more"\n', encoding="utf-8")
    assert om.known_differences(str(good)) == {
        ("grid", "4", "CR", "max"): 'see ("a section"), then more'}


def test_the_original_started_where_graph_mode_starts():
    """The runs used the project's default start positions, as graph mode does."""
    for map_name, robots in sorted({(r["map"], r["robots"]) for r in ROWS}):
        starts = {tuple(r["start_vertices"]) for r in ROWS
                  if (r["map"], r["robots"]) == (map_name, robots)}
        assert starts == {tuple(om.start_vertices(map_name, robots))}, (map_name, robots)


COMPARED = sorted(k for k in CELLS if not om.fully_known(KNOWN, *k[:3]))


def test_most_cells_are_compared():
    assert len(COMPARED) >= len(CELLS) // 2


@pytest.mark.parametrize("key", COMPARED, ids=lambda k: f"{k[0]}-{k[1]}-{k[2]}")
def test_graph_mode_within_tolerance_of_the_original(key):
    map_name, robots, alg, duration = key
    graph = [om.graph_run(map_name, robots, alg, s, duration) for s in om.SEEDS]
    cmp = om.compare(om.mean_figures(CELLS[key]), om.mean_figures([g[:3] for g in graph]))
    problems = []
    for m in om.METRICS:
        rel, ok = cmp[m]
        if not ok and not om.known_reason(KNOWN, map_name, robots, alg, m):
            problems.append(f"{m} {rel:+.1%} (tolerance {om.TOL[m]:.0%})")
        listed = KNOWN.get((map_name, str(robots), alg, m))
        if ok and listed:
            problems.append(f"{m} {rel:+.1%} is within tolerance although listed as a known "
                            f"difference ({listed})")
    assert not problems, f"{map_name} {robots} {alg}: " + "; ".join(problems)
