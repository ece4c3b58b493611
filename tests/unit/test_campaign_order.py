"""Run order of a campaign: the grid's keys in file order, the first varying slowest. The
shipped reference campaign puts the seed first, so a partial run covers every cell; the run
keys do not depend on the order (a reordered file resumes the same runs)."""
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))

from patrolling_sim.campaign.spec import load_campaign  # noqa: E402

CODE = {"commit": "test", "dirty": False}


def test_reference_campaign_is_seed_first():
    c = load_campaign(os.path.join(ROOT, "campaigns", "reference.yaml"), code=CODE)
    cells = {(r.config["map"], r.config["robots"], r.config["alg"]) for r in c.runs}
    seeds = sorted({r.config["seed"] for r in c.runs})
    assert seeds == list(range(10)) and len(c.runs) == 10 * len(cells)
    assert {r.config["robots"] for r in c.runs} == {1, 2, 4, 6, 8, 12}
    first = c.runs[:len(cells)]
    assert {r.config["seed"] for r in first} == {0}
    assert {(r.config["map"], r.config["robots"], r.config["alg"]) for r in first} == cells
    # seeds never go back: a prefix of the order is "seeds 0..s-1 complete, some of s"
    order = [r.config["seed"] for r in c.runs]
    assert order == sorted(order)
    assert all(r.config["duration"] == 3600 for r in c.runs)


def test_order_does_not_change_the_keys(tmp_path):
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    a.write_text("mode: graph\nfixed: {duration: 60}\ngrid:\n  map: [grid, 1r5]\n"
                 "  alg: [CR, DTAG]\nseeds: 2\n")
    b.write_text("mode: graph\nfixed: {duration: 60}\ngrid:\n  seed: [0, 1]\n"
                 "  alg: [CR, DTAG]\n  map: [grid, 1r5]\n")
    ra, rb = load_campaign(str(a), code=CODE).runs, load_campaign(str(b), code=CODE).runs
    assert [r.config["seed"] for r in ra] == [0, 1] * 4
    assert [r.config["seed"] for r in rb] == [0] * 4 + [1] * 4
    assert [r.config["map"] for r in rb[:4]] == ["grid", "1r5", "grid", "1r5"]
    assert sorted(r.key for r in ra) == sorted(r.key for r in rb)
