"""Policy files (docs/learning.md, "Policy files"): a trained slot-scoring network as a
numpy ``.npz`` archive, read and run without any learning library.

The archive holds ``W0, b0, W1, b1, ...`` (float arrays: layer l maps ``x`` to
``act(x @ W_l + b_l)``, no activation after the last layer, which has one output: the
score of a slot) and ``meta``, a JSON text::

    {"format": "patrolling_sim.policy", "version": 1,
     "observation": "slots", "features": [the names of slots.SLOT_FEATURES],
     "feature_count": K, "layers": [K, 32, 32, 1], "activation": "tanh",
     "speed": 1.0, "training": {...a summary, free form...}}

``speed`` is the robot speed (m/s) the time scale T was computed with in training; the
``POLICY`` strategy uses it too. A robot takes the valid slot of highest score (greedy), or
draws one from the softmax of the scores over the valid slots.

:func:`load_policy` checks everything: a missing, unreadable or corrupt file, another
format or version, an unknown observation mode, a feature list that differs from this
code's, or weights of the wrong shape raise :class:`PatrolInputError` with one line naming
the file. A policy's label is ``<file stem>@<first 8 hex digits of the file's sha256>``.
"""
import hashlib
import json
import math
import os
import zipfile

import numpy as np

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.learned.slots import SLOT_FEATURES

FORMAT = "patrolling_sim.policy"
VERSION = 1
OBSERVATIONS = ("slots",)
ACTIVATIONS = {"tanh": np.tanh, "relu": lambda x: np.maximum(x, 0.0)}


class Policy:
    """A loaded policy file: ``meta`` (dict), ``weights`` [(W, b)], ``path``, ``sha256``,
    ``label``."""

    def __init__(self, path, meta, weights, sha256):
        self.path, self.meta, self.weights, self.sha256 = path, meta, weights, sha256
        self.label = file_label(path, sha256)
        self.act_fn = ACTIVATIONS[meta["activation"]]
        self.speed = float(meta.get("speed", 1.0))

    def scores(self, features) -> np.ndarray:
        """The score of every row of ``features`` (..., K): (...,) float64."""
        x = np.asarray(features, dtype=np.float64)
        last = len(self.weights) - 1
        for k, (W, b) in enumerate(self.weights):
            x = x @ W + b
            if k < last:
                x = self.act_fn(x)
        return x[..., 0]

    def choose(self, features, mask, rng=None) -> int:
        """The slot chosen among the valid ones (``mask``, D bools) of ``features`` (D, K):
        the first of highest score, or (with ``rng``, a ``random.Random``) one drawn from the
        softmax of the valid slots' scores."""
        s = self.scores(features)
        valid = np.flatnonzero(mask)
        if valid.size == 0:
            return 0
        sv = s[valid]
        if rng is None:
            return int(valid[int(np.argmax(sv))])
        p = np.exp(sv - sv.max())
        p /= p.sum()
        u = rng.random()
        acc = 0.0
        for k, q in zip(valid, p):
            acc += q
            if u < acc:
                return int(k)
        return int(valid[-1])


def file_sha256(path) -> str:
    """Hex sha256 of the file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 16), b""):
            h.update(chunk)
    return h.hexdigest()


def file_label(path, sha256=None) -> str:
    """The label of the file ``path``: ``<file stem>@<first 8 hex digits of its sha256>``
    (``sha256``: the file's digest if the caller has it). It names the file's content: a
    changed file gets a new label, a copy elsewhere under the same name the same one."""
    stem = os.path.splitext(os.path.basename(path))[0]
    return f"{stem}@{(sha256 or file_sha256(path))[:8]}"


def save_policy(path, weights, meta) -> str:
    """Write ``weights`` [(W, b)] and ``meta`` (dict, completed with the format, version,
    features and layer sizes) to ``path`` (.npz); returns the file's label."""
    meta = dict(meta)
    meta.update(format=FORMAT, version=VERSION,
                features=list(meta.get("features", SLOT_FEATURES)),
                feature_count=int(np.asarray(weights[0][0]).shape[0]),
                layers=[int(np.asarray(weights[0][0]).shape[0])]
                + [int(np.asarray(W).shape[1]) for W, _ in weights])
    arrays = {}
    for k, (W, b) in enumerate(weights):
        arrays[f"W{k}"] = np.asarray(W, dtype=np.float64)
        arrays[f"b{k}"] = np.asarray(b, dtype=np.float64)
    with open(path, "wb") as f:
        np.savez_compressed(f, meta=np.array(json.dumps(meta, sort_keys=True)), **arrays)
    return load_policy(path).label


def _bad(path, what):
    return PatrolInputError(f"policy file {path}: {what}")


def _read(path):
    """(meta dict, {name: array}) of the archive ``path``; PatrolInputError if unreadable."""
    if not path:
        raise PatrolInputError("POLICY needs a policy file (--policy FILE, or the 'policy' key)")
    if not os.path.isfile(path):
        raise _bad(path, "not found")
    if not zipfile.is_zipfile(path):
        raise _bad(path, "not a .npz archive")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as e:
        raise _bad(path, f"not a readable .npz archive ({str(e).splitlines()[0][:80]})")
    if "meta" not in arrays:
        raise _bad(path, "no 'meta' entry")
    try:
        meta = json.loads(str(arrays.pop("meta")))
    except ValueError:
        raise _bad(path, "its 'meta' entry is not JSON")
    if not isinstance(meta, dict):
        raise _bad(path, "its 'meta' entry is not a JSON object")
    return meta, arrays


def _check_meta(path, meta):
    if meta.get("format") != FORMAT or meta.get("version") != VERSION:
        raise _bad(path, f"format {meta.get('format')!r} version {meta.get('version')!r}, "
                         f"expected {FORMAT!r} version {VERSION}")
    if meta.get("observation") not in OBSERVATIONS:
        raise _bad(path, f"unknown observation mode {meta.get('observation')!r} (known: "
                         f"{', '.join(OBSERVATIONS)})")
    if meta.get("feature_count") != len(SLOT_FEATURES) or \
            list(meta.get("features") or []) != list(SLOT_FEATURES):
        raise _bad(path, f"{meta.get('feature_count')!r} features, this code has "
                         f"{len(SLOT_FEATURES)} ({', '.join(SLOT_FEATURES)})")
    if meta.get("activation") not in ACTIVATIONS:
        raise _bad(path, f"unknown activation {meta.get('activation')!r}")
    speed = meta.get("speed", 1.0)
    if not isinstance(speed, (int, float)) or not speed > 0 or not math.isfinite(speed):
        raise _bad(path, f"speed must be a number > 0, got {speed!r}")


def _weights(path, meta, arrays):
    layers = meta.get("layers")
    if not isinstance(layers, list) or len(layers) < 2 or layers[0] != len(SLOT_FEATURES) \
            or layers[-1] != 1:
        raise _bad(path, f"layers {layers!r}: expected [{len(SLOT_FEATURES)}, ..., 1]")
    weights = []
    for k in range(len(layers) - 1):
        W, b = arrays.get(f"W{k}"), arrays.get(f"b{k}")
        shape = (layers[k], layers[k + 1])
        if W is None or b is None or W.shape != shape or b.shape != (shape[1],):
            raise _bad(path, f"layer {k}: expected W{k} {shape} and b{k} ({shape[1]},)")
        if W.dtype.kind != "f" or b.dtype.kind != "f" or not (
                np.isfinite(W).all() and np.isfinite(b).all()):
            raise _bad(path, f"layer {k}: weights must be finite floats")
        weights.append((W.astype(np.float64), b.astype(np.float64)))
    return weights


_CACHE = {}


def load_policy(path) -> Policy:
    """The checked :class:`Policy` of file ``path`` (module docstring); the agents of one
    process share one copy per file content. Raises PatrolInputError (one line)."""
    meta, arrays = _read(path)
    _check_meta(path, meta)
    weights = _weights(path, meta, arrays)
    digest = file_sha256(path)
    key = (os.path.abspath(path), digest)
    if key not in _CACHE:
        _CACHE[key] = Policy(path, meta, weights, digest)
    return _CACHE[key]
