"""DTAG and DTAP give the same runs as before the speed-up of algorithms/dta_common.py: the
visit log and idleness log of fixed-seed graph-mode runs (a small map, a few robots, 600 s)
hash to the fingerprints recorded before the change (sha256 of the files' bytes)."""
import hashlib
import os
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "patrolling_sim", "src"))

from patrolling_sim.graphsim.simulator import GraphSimulator  # noqa: E402
from patrolling_sim.graphsim.config import GraphSimConfig  # noqa: E402

#: (alg, map, robots, seed) -> sha256 of _visits.csv + _idleness.csv, recorded before the
#: speed-up (commit "test: DTA fingerprints")
FINGERPRINTS = {
    ("DTAG", "cumberland", 4, 0):
        "2a43e082ce3a11e397fe01dfe3da4803c997ef87e9ae6505148390fb6df967ec",
    ("DTAG", "cumberland", 4, 1):
        "0caa1294670e443a6c141e41a50f792a824744a7447bbdbc2ab791097627da78",
    ("DTAP", "cumberland", 4, 0):
        "8939aa87cd334ceb899b33d0f0f03456611b2d80474d126dbba41c387eccf92a",
    ("DTAP", "cumberland", 4, 1):
        "71106763d6bb700f692553d1ddbcac5f533661be66343f668777f547f795f197",
    # a large team on a small map: thousands of merged messages
    ("DTAG", "DIAG_labs", 12, 0):
        "9283d33097867ceff2d559fb519aea0e8ec2c0fb3a567b1fb84c4f4e61493e2c",
    ("DTAP", "DIAG_labs", 12, 0):
        "540e68ee18eab27f31143ea950b32eeb4d8cff9141267c02116c66fc9ce29a54",
}


def fingerprint(alg, map_name, robots, seed, tmp):
    sim = GraphSimulator(GraphSimConfig(map=map_name, robots=robots, alg=alg, seed=seed,
                                        duration=600, results_dir=str(tmp)))
    sim.run(write=True)
    h = hashlib.sha256()
    for suffix in ("_visits.csv", "_idleness.csv"):
        with open(sim.prefix + suffix, "rb") as f:
            h.update(f.read())
    return h.hexdigest(), sim.messages_sent


@pytest.mark.parametrize("case", sorted(FINGERPRINTS))
def test_dta_runs_unchanged(case, tmp_path):
    digest, sent = fingerprint(*case, tmp_path)
    assert sent > 100                          # the merge path is exercised
    assert digest == FINGERPRINTS[case]


def test_decode_seconds_is_the_old_conversion():
    from patrolling_sim.algorithms.dta_common import (IdlenessEstimate, decode_idleness,
                                                      decode_seconds)
    from patrolling_sim.model.graph import PatrolGraph, load_graph
    g, other = (PatrolGraph(load_graph(os.path.join(ROOT, "maps", m, m + ".graph")))
                for m in ("1r5", "grid"))
    n = g.n
    assert other.n != n
    data = [3, 40] + [0, 17, 32767, -32768, 5] + [7] * (n - 5) + [2]
    sec, nxt = decode_seconds(data, g)
    ten, nxt2 = decode_idleness(data, n)
    assert nxt == nxt2 == 2 and sec.tolist() == (ten / 10.0).tolist()
    assert not sec.flags.writeable
    assert decode_seconds(data, other) is None
    assert decode_seconds([3, 41] + data[2:], g) is None
    # kept with the graph (not in the module), one conversion per content
    assert g.derived["dta_decoded"][tuple(data)][0] is sec
    assert decode_seconds(list(data), g)[0] is sec and "dta_decoded" not in other.derived
    a, b = IdlenessEstimate(n, 100.0, 0.0), IdlenessEstimate(n, 100.0, 0.0)
    a.merge(ten, 3.5)
    b.merge_seconds(sec, 3.5)
    assert a.values.tolist() == b.values.tolist() and a.t == b.t == 3.5


def test_versioned_dict_counts_every_change():
    from patrolling_sim.algorithms.dta_common import VersionedDict
    d = VersionedDict()
    seen = [d.version]
    d[1] = (2.0, 0)
    d.setdefault(2, (1.0, 1))
    d.update({3: (0.5, 2)})
    d.pop(3)
    del d[2]
    d |= {4: (1.0, 0)}
    d.popitem()
    d.clear()
    assert d.version == 8 and seen == [0] and d == {}
    _ = d.get(1), list(d.items())
    assert d.version == 8                      # reading does not count
