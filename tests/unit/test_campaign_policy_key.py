"""Campaign run keys name a policy file by its content (campaign.spec.keyed_config): a
changed file at the same path is a new run, a copy of the file elsewhere under the same
name is the same run, and the keys of the other algorithms' runs are what they were."""
import hashlib
import json
import os
import shutil

import yaml

from patrolling_sim.campaign.spec import load_campaign
from patrolling_sim.learned.policyfile import load_policy, save_policy

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SHIPPED = os.path.join(ROOT, "policies", "slots_bc.npz")
CODE = {"commit": "abc", "dirty": False}


def _keys(tmp_path, alg, policy, name="c.yaml"):
    """{seed: run key} of a two-run campaign of ``alg`` with ``policy`` in ``fixed``."""
    data = {"name": "k", "mode": "graph", "fixed": {"duration": 60, "policy": str(policy)},
            "grid": {"map": ["grid"], "robots": [2], "alg": [alg]}, "seeds": 2}
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return {r.config["seed"]: r.key for r in load_campaign(str(path), code=CODE).runs}


def _altered_copy(src, dst):
    """A valid policy file at ``dst``: ``src``'s network with its last bias moved."""
    pol = load_policy(str(src))
    weights = [(W.copy(), b.copy()) for W, b in pol.weights]
    weights[-1][1][0] += 0.5
    save_policy(str(dst), weights, pol.meta)


def _old_key(config):
    """The key as it was before files were named by content (the path as given)."""
    blob = json.dumps({"mode": "graph", "config": config, "code": CODE["commit"]},
                      sort_keys=True, default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:16]


def test_a_changed_policy_file_at_the_same_path_is_a_new_run(tmp_path):
    path = tmp_path / "p" / "mine.npz"
    path.parent.mkdir()
    shutil.copy(SHIPPED, path)
    before = _keys(tmp_path, "POLICY", path)
    assert before == _keys(tmp_path, "POLICY", path)                  # stable
    _altered_copy(SHIPPED, path)
    after = _keys(tmp_path, "POLICY", path)
    assert not set(before.values()) & set(after.values())


def test_the_same_policy_file_at_two_paths_is_the_same_run(tmp_path):
    a, b = tmp_path / "a" / "mine.npz", tmp_path / "b" / "mine.npz"
    for p in (a, b):
        p.parent.mkdir()
        shutil.copy(SHIPPED, p)
    assert _keys(tmp_path, "POLICY", a) == _keys(tmp_path, "POLICY", b)


def test_other_algorithms_keep_their_keys_and_read_no_file(tmp_path):
    # a policy path that does not exist: other algorithms ignore it, so their keys do not
    # need the file; every key is byte for byte the one of the path as given
    missing = tmp_path / "nowhere.npz"
    keys = _keys(tmp_path, "CR", missing)
    camp = load_campaign(str(tmp_path / "c.yaml"), code=CODE)
    assert [r.key for r in camp.runs] == [_old_key(r.config) for r in camp.runs]
    assert sorted(keys.values()) == sorted(r.key for r in camp.runs)
    # and a POLICY run is not keyed by its path: the old formula gives another key
    path = tmp_path / "mine.npz"
    shutil.copy(SHIPPED, path)
    _keys(tmp_path, "POLICY", path)
    camp = load_campaign(str(tmp_path / "c.yaml"), code=CODE)
    assert all(r.key != _old_key(r.config) for r in camp.runs)
    assert all(r.config["policy"] == str(path) for r in camp.runs)        # config as given
