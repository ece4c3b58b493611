"""Significance tests between algorithms (replacing the original's R ANOVA scripts).

For every comparison group (same map, team size and varying settings) with at least two
algorithms:

- Kruskal-Wallis H test over the algorithms,
- pairwise two-sided Mann-Whitney U tests, p-values adjusted with Holm's step-down method
  over the pairs of that group.

What is compared (the ``basis`` column):

- ``run means`` -- each run's mean idleness is one observation. Used when every algorithm in
  the group has at least two runs: repetitions are the independent units, the thousands of
  samples inside one run are not independent.
- ``samples`` -- every idleness sample is one observation. Used when some algorithm has a
  single run; the p-values then compare those particular runs, not the algorithms in general.
"""
import itertools

import numpy as np
import pandas as pd
from scipy import stats as sps

from patrolling_sim.report.table import group_columns


def holm(pvalues):
    """Holm-Bonferroni adjusted p-values, in the input order."""
    p = np.asarray(pvalues, dtype=float)
    m = p.size
    order = np.argsort(p, kind="stable")
    adj = np.empty(m)
    running = 0.0
    for rank, idx in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[idx]))
        adj[idx] = running
    return adj


def _kruskal(groups):
    try:
        h, p = sps.kruskal(*groups)
    except ValueError:          # all values identical
        return np.nan, 1.0
    return float(h), (1.0 if np.isnan(p) else float(p))


def _mwu(a, b):
    try:
        u, p = sps.mannwhitneyu(a, b, alternative="two-sided")
    except ValueError:
        return np.nan, 1.0
    return float(u), (1.0 if np.isnan(p) else float(p))


def significance(runs, per_run):
    """Return a DataFrame with one row per algorithm pair of every comparison group:
    group columns (without algorithm), basis, algorithm_a, algorithm_b, n_a, n_b,
    median_a, median_b, kruskal_H, kruskal_p, U, p_raw, p_holm."""
    gcols = [c for c in group_columns(per_run) if c != "algorithm"]
    by_prefix = {r.prefix: r for r in runs}
    rows = []
    for key, g in per_run.groupby(gcols, sort=True, dropna=False):
        key = key if isinstance(key, tuple) else (key,)
        algs = sorted(g["algorithm"].unique())
        if len(algs) < 2:
            continue
        counts = g[g["samples"] > 0].groupby("algorithm").size()
        use_means = all(counts.get(a, 0) >= 2 for a in algs)
        data = {}
        for a in algs:
            ga = g[g["algorithm"] == a]
            if use_means:
                data[a] = ga["avg_idleness"].dropna().to_numpy(dtype=float)
            else:
                data[a] = np.concatenate([by_prefix[p].samples["Idleness"].to_numpy(dtype=float)
                                          for p in ga["prefix"]])
        algs = [a for a in algs if data[a].size]
        if len(algs) < 2:
            continue
        h, kp = _kruskal([data[a] for a in algs])
        pairs = list(itertools.combinations(algs, 2))
        tests = [_mwu(data[a], data[b]) for a, b in pairs]
        adj = holm([t[1] for t in tests])
        for (a, b), (u, p), pa in zip(pairs, tests, adj):
            row = dict(zip(gcols, key))
            row.update(basis="run means" if use_means else "samples",
                       algorithm_a=a, algorithm_b=b, n_a=int(data[a].size),
                       n_b=int(data[b].size), median_a=float(np.median(data[a])),
                       median_b=float(np.median(data[b])), kruskal_H=h, kruskal_p=kp,
                       U=u, p_raw=p, p_holm=float(pa))
            rows.append(row)
    cols = gcols + ["basis", "algorithm_a", "algorithm_b", "n_a", "n_b", "median_a",
                    "median_b", "kruskal_H", "kruskal_p", "U", "p_raw", "p_holm"]
    return pd.DataFrame(rows, columns=cols)


def pvalue_matrices(sig, gcols):
    """Yield (key dict, basis, kruskal_H, kruskal_p, matrix DataFrame of Holm p-values
    (algorithms x algorithms, diagonal empty)) per comparison group."""
    if sig.empty:
        return
    for key, g in sig.groupby(gcols, sort=True, dropna=False):
        key = key if isinstance(key, tuple) else (key,)
        algs = sorted(set(g["algorithm_a"]) | set(g["algorithm_b"]))
        m = pd.DataFrame(np.nan, index=algs, columns=algs)
        for _, r in g.iterrows():
            m.loc[r["algorithm_a"], r["algorithm_b"]] = r["p_holm"]
            m.loc[r["algorithm_b"], r["algorithm_a"]] = r["p_holm"]
        first = g.iloc[0]
        yield (dict(zip(gcols, key)), first["basis"], first["kruskal_H"], first["kruskal_p"], m)
