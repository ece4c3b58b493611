"""The POLICY strategy and policy files (docs/learning.md, docs/algorithms/POLICY.md): the
file format round trip and its checks, one-line errors before anything runs, the numpy
inference against torch, a graph-mode run that patrols every vertex, the report's label."""
import importlib.util
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from patrolling_sim.algorithms.base import display_name
from patrolling_sim.algorithms.policy import DEFAULT_POLICY
from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.graphsim.cli import main as graph_sim_main
from patrolling_sim.graphsim.config import GraphSimConfig
from patrolling_sim.graphsim.simulator import GraphSimulator
from patrolling_sim.learned.policyfile import file_sha256, load_policy, save_policy
from patrolling_sim.learned.slots import K, SLOT_FEATURES
from patrolling_sim.runner.config import ExperimentConfig

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SHIPPED = paths.policy_file(DEFAULT_POLICY)


def weights(seed=0, hidden=8):
    rng = np.random.default_rng(seed)
    return [(rng.normal(size=(K, hidden)), rng.normal(size=hidden)),
            (rng.normal(size=(hidden, 1)), rng.normal(size=1))]


def write(path, w=None, **meta):
    base = {"observation": "slots", "activation": "tanh", "speed": 1.0}
    base.update(meta)
    return save_policy(str(path), w or weights(), base)


def test_round_trip_and_label(tmp_path):
    p = tmp_path / "mine.npz"
    w = weights(3)
    label = write(p, w, training={"note": "test"})
    pol = load_policy(str(p))
    assert label == pol.label == f"mine@{file_sha256(str(p))[:8]}"
    for (W, b), (W2, b2) in zip(w, pol.weights):
        assert np.array_equal(W, W2) and np.array_equal(b, b2)
    assert pol.meta["features"] == list(SLOT_FEATURES) and pol.meta["layers"] == [K, 8, 1]
    x = np.random.default_rng(1).normal(size=(5, K))
    expect = np.tanh(x @ w[0][0] + w[0][1]) @ w[1][0] + w[1][1]
    assert np.allclose(pol.scores(x), expect[:, 0])
    mask = np.array([True, False, True, False, False])
    assert pol.choose(x, mask) == [0, 2][int(np.argmax(expect[[0, 2], 0]))]


def rewrite_meta(src, dst, **changes):
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays.pop("meta")))
    meta.update(changes)
    np.savez(dst, meta=np.array(json.dumps(meta)), **arrays)


@pytest.mark.parametrize("change, words", [
    ({"feature_count": K + 1}, "features"),
    ({"observation": "pixels"}, "unknown observation mode"),
    ({"version": 99}, "version"),
    ({"activation": "sigmoid"}, "unknown activation"),
])
def test_mismatched_files_are_refused(tmp_path, change, words):
    good = tmp_path / "good.npz"
    write(good)
    bad = tmp_path / "bad.npz"
    rewrite_meta(str(good), str(bad), **change)
    with pytest.raises(PatrolInputError, match=words) as e:
        load_policy(str(bad))
    assert str(bad) in str(e.value) and "\n" not in str(e.value)


def test_wrong_weight_shape_is_refused(tmp_path):
    p = tmp_path / "shape.npz"
    write(p)
    with np.load(p) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["W0"] = arrays["W0"][:, :3]
    np.savez(p, **arrays)
    with pytest.raises(PatrolInputError, match="layer 0"):
        load_policy(str(p))


def bad_files(tmp_path):
    garbage = tmp_path / "garbage.npz"
    garbage.write_text("not an archive\n")
    nometa = tmp_path / "nometa.npz"
    np.savez(nometa, W0=np.zeros((K, 1)))
    return [str(tmp_path / "missing.npz"), str(garbage), str(nometa)]


def test_bad_policy_file_is_one_line_exit_2_before_any_run(tmp_path, capsys):
    out = tmp_path / "results"
    for f in bad_files(tmp_path):
        rc = graph_sim_main(["--alg", "POLICY", "--robots", "2", "--policy", f,
                             "--duration", "60", "--results-dir", str(out), "--quiet"])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and err.count("\n") == 0 and f in err, err
    assert not out.exists() or not any(out.rglob("*_info.csv"))
    # the program itself, once
    r = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "graph_sim.py"),
                        "--alg", "POLICY", "--policy", str(tmp_path / "missing.npz"),
                        "--results-dir", str(out)], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "missing.npz" in r.stderr


def test_runner_and_campaign_configs_check_the_policy(tmp_path):
    missing = str(tmp_path / "missing.npz")
    cfg = ExperimentConfig(map="grid", robots=2, alg="POLICY", nav="abstract", policy=missing,
                           results_dir=str(tmp_path))
    with pytest.raises(PatrolInputError, match="missing.npz: not found"):
        cfg.validate()
    with pytest.raises(PatrolInputError, match="policy_mode"):
        GraphSimConfig(alg="POLICY", params={"policy_mode": "best"}).validate()
    # another algorithm ignores the key
    GraphSimConfig(alg="CR", robots=2, policy=missing).validate()


def test_shipped_policy_patrols_every_vertex_in_graph_mode():
    sim = GraphSimulator(GraphSimConfig(map="grid", robots=4, alg="POLICY", duration=600,
                                        seed=1, policy=SHIPPED))
    stats = sim.run(write=False)
    label = load_policy(SHIPPED).label
    assert sim.robots[0].core.strategy.algorithm_params == label
    visited = {v for v in range(sim.g.n) if sim.monitor.last_visit[v] > 0}
    assert visited == set(range(sim.g.n)), sorted(set(range(sim.g.n)) - visited)
    assert stats.total_visits > sim.g.n


def test_sampled_mode_is_seeded():
    def run(seed):
        sim = GraphSimulator(GraphSimConfig(map="cumberland", robots=3, alg="POLICY",
                                            duration=300, seed=seed,
                                            params={"policy_mode": "sample"}))
        s = sim.run(write=False)
        return s.total_visits, s.global_avg
    assert run(2) == run(2)


def test_report_names_policy_runs_by_their_file():
    assert display_name("POLICY", "slots_bc@0123abcd") == "POLICY slots_bc@0123abcd"
    assert display_name("POLICY", "") == "POLICY"
    assert display_name("DTAG", "1,2") == "DTAG"


def load_trainer():
    spec = importlib.util.spec_from_file_location(
        "train_policy", os.path.join(ROOT, "scripts", "train_policy.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_numpy_inference_equals_the_torch_forward(tmp_path):
    torch = pytest.importorskip("torch")
    trainer = load_trainer()
    torch.manual_seed(0)
    nets = trainer.Nets(torch, 16, 1e-3)
    x = np.random.default_rng(0).normal(size=(7, 5, K)).astype(np.float32)
    with torch.no_grad():
        expect = nets.actor(torch.from_numpy(x)).squeeze(-1).double().numpy()
    p = tmp_path / "torch.npz"
    save_policy(str(p), nets.numpy_weights(), {"observation": "slots", "activation": "tanh"})
    assert np.allclose(load_policy(str(p)).scores(x), expect, atol=1e-5)
