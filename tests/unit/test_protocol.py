"""The /results numbers are named once (patrolling_sim.common.protocol) and agree with the
protocol document and with every module that uses them."""
import ast
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
    """Message numbers are integer literals in common/protocol.py only: every other module
    names them from there."""
    pkg = os.path.join(ROOT, "src", "patrolling_sim", "src", "patrolling_sim")
    elsewhere = []
    for d, _, files in os.walk(pkg):
        for f in files:
            path = os.path.join(d, f)
            if not f.endswith(".py") or path.endswith(os.path.join("common", "protocol.py")):
                continue
            for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
                if (isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant)
                        and any(isinstance(t, ast.Name) and t.id.startswith("MSG_")
                                for t in node.targets)):
                    elsewhere.append(f"{path}:{node.lineno}")
    assert not elsewhere, elsewhere
    assert base.MSG_FAILURE is protocol.MSG_ROBOT_STATUS
    assert watch.GO is protocol.GO and watch.END is protocol.END
    assert protocol.INT16_CAP < protocol.INT16_MAX == 2 ** 15 - 1
