"""One registry: a module dropped into the algorithms package is found by graph mode and by
the runner's validation with no other edit; a broken module is a one-line warning."""
import logging
import sys

import pytest

from patrolling_sim import algorithms
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.runner.config import ExperimentConfig

NEW_MODULE = '''
from patrolling_sim.algorithms.base import PatrolStrategy, register


@register
class FirstNeighbour(PatrolStrategy):
    """Always the first neighbour of the current vertex."""
    name = "ZZ_FIRST"

    def choose_next(self, now):
        return self.graph.neighbor_ids(self.current)[0]
'''


@pytest.fixture
def extra_dir(tmp_path):
    """A temporary directory on the algorithms package's path; undone afterwards."""
    before = set(algorithms.REGISTRY)
    algorithms.__path__.append(str(tmp_path))
    yield tmp_path
    algorithms.__path__.remove(str(tmp_path))
    for name in set(algorithms.REGISTRY) - before:
        del algorithms.REGISTRY[name]
    for mod in ("zz_first", "zz_broken"):
        algorithms.loaded.pop(mod, None)
        algorithms.failed.pop(mod, None)
        sys.modules.pop(f"{algorithms.__name__}.{mod}", None)


def test_shipped_modules_are_discovered():
    # every module file of the package was imported, and every one of them loaded
    assert algorithms.failed == {}
    assert {"cr", "cgg", "dtap", "msp"} <= set(algorithms.loaded)
    assert {"CR", "CGG", "DTAP", "MSP"} <= set(algorithms.names())


def test_dropped_module_is_found_everywhere(extra_dir, tmp_path):
    (extra_dir / "zz_first.py").write_text(NEW_MODULE)
    assert "ZZ_FIRST" not in algorithms.REGISTRY
    algorithms.discover()
    assert "ZZ_FIRST" in algorithms.names()
    # graph mode runs it
    cfg = GraphSimConfig(map="grid", robots=2, alg="ZZ_FIRST", duration=120,
                         results_dir=str(tmp_path))
    stats = GraphSimulator(cfg).run(write=False)
    assert stats.total_visits > 10
    # the runner accepts it
    ExperimentConfig(map="grid", robots=2, alg="ZZ_FIRST", timeout=60).validate(
        check_start_positions=False, check_writable=False)


def test_broken_module_is_one_warning(extra_dir, caplog):
    (extra_dir / "zz_broken.py").write_text("import no_such_module_anywhere\n")
    with caplog.at_level(logging.WARNING, logger=algorithms.__name__):
        algorithms.discover()
    msgs = [r.getMessage() for r in caplog.records]
    assert len(msgs) == 1 and "\n" not in msgs[0]
    assert str(extra_dir / "zz_broken.py") in msgs[0] and "no_such_module_anywhere" in msgs[0]
    assert "CR" in algorithms.REGISTRY
