"""The /results numbers are named once (patrolling_sim.common.protocol) and agree with the
protocol document and with every module that uses them."""
import os
import re

from patrolling_sim.common import protocol
from patrolling_sim.algorithms import base
from patrolling_sim.runner import watch

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def test_documented_types_are_named():
    with open(os.path.join(ROOT, "docs", "protocol.md"), encoding="utf-8") as f:
        rows = re.findall(r"^\| (\d+) \| `\[(-?\w+), (\d+)(?:, (\d+))?", f.read(), re.M)
    assert len(rows) >= 9
    types = {v for k, v in vars(protocol).items() if k.startswith("MSG_")}
    for kind, sender, kind2, payload in rows:
        assert int(kind) == int(kind2) and int(kind) in types, kind
        if sender == "-1":
            assert int(payload) in (protocol.GO, protocol.END)
    assert protocol.MSG_ROBOT_STATUS == 13
    assert all(t < protocol.FIRST_ALGORITHM_TYPE for t in (
        protocol.MSG_INIT, protocol.MSG_TARGET_REACHED, protocol.MSG_INTERFERENCE,
        protocol.MSG_ROBOT_STATUS))


def test_one_definition():
    for name in ("MSG_INIT", "MSG_TARGET_REACHED", "MSG_DTA_IDLENESS", "INT16_CAP",
                 "INT16_MAX", "MSG_SSI_BID"):
        assert getattr(base, name) is getattr(protocol, name)
    assert watch.GO is protocol.GO and watch.END is protocol.END
    assert protocol.INT16_CAP < protocol.INT16_MAX == 2 ** 15 - 1
