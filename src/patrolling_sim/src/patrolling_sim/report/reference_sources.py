"""The runs behind the reference tables: one base campaign, and campaigns that replace some
of its algorithms or add new ones.

When an algorithm's code changes, only its rows of the reference tables are stale. Rather
than re-running every algorithm (a campaign's run keys include the code commit), a second
campaign re-runs the changed algorithms over the same grid, and its runs *replace* that
algorithm's runs of the base campaign: every run of an algorithm then comes from exactly one
campaign, never two, and the pages name the campaign and code commit of each algorithm. A
campaign may also *add* an algorithm the base lacks (e.g. a learned policy), over the base's
whole grid of maps, team sizes and seeds.

:func:`merge_sources` takes the base folder and the replacing folders and returns the merged
runs with one :class:`Source` per folder; :func:`display_names` names each algorithm as the
reports do (a learned policy with its file's label).
"""
import os
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import yaml

from patrolling_sim.algorithms.base import display_name
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.monitor.results import parse_info_line

#: the columns naming a run within a campaign's grid
RUN_ID = ["map", "robots", "alg", "seed"]


@dataclass
class Source:
    """One campaign folder of the tables: its provenance and the algorithms taken from it."""
    folder: str
    provenance: dict
    algs: List[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return str(self.provenance.get("name", os.path.basename(os.path.abspath(self.folder))))

    @property
    def commit(self) -> str:
        return str((self.provenance.get("code") or {}).get("commit", "unknown"))

    @property
    def dirty(self) -> bool:
        return bool((self.provenance.get("code") or {}).get("dirty"))

    def line(self) -> str:
        """One Markdown line: the campaign, its code commit, its run period, its algorithms."""
        p = self.provenance
        return (f"campaign `{self.name}` (file `{os.path.basename(str(p.get('file', '?')))}`, "
                f"code commit `{self.commit[:12]}`{' (dirty)' if self.dirty else ''}, run from "
                f"{p.get('start', '?')} to {p.get('end', '?')} on `{p.get('client_host', '?')}`)"
                f": {', '.join(self.algs)}")


def read_provenance(folder: str) -> dict:
    """``provenance.yaml`` of a campaign folder as a dict (empty if absent or unreadable)."""
    try:
        with open(os.path.join(folder, "provenance.yaml")) as f:
            d = yaml.safe_load(f)
        return d if isinstance(d, dict) else {}
    except (OSError, yaml.YAMLError):
        return {}


def config_columns(df) -> List[str]:
    """The columns of a runs.csv that are settings: those before ``status``, other than the
    run's key, mode and :data:`RUN_ID`."""
    status_at = list(df.columns).index("status")
    return [c for c in list(df.columns)[:status_at] if c not in ("key", "mode", *RUN_ID)]


def merge_sources(base: str, replacements: Sequence[str],
                  load: Callable[[str], object]) -> Tuple[object, List[Source]]:
    """(runs, sources): the runs of the campaign folder ``base`` in which every algorithm
    present in a folder of ``replacements`` has its runs from that folder instead (an
    algorithm the base lacks is added, if its runs cover the base's whole grid).

    ``load`` reads one folder's ``runs.csv`` as a checked DataFrame (the reference tables'
    loader). The first :class:`Source` is the base (the algorithms it still provides), then
    one per replacement, in order.

    Raises:
        PatrolInputError: one line naming the folder, if a replacing folder holds an
            algorithm another folder already replaces, or its runs of an algorithm are not
            the same grid (maps, team sizes, seeds) as the base's runs of that algorithm (of
            any algorithm, for an added one), or a setting (duration, speed, ...) differs
            from the base's.
    """
    import pandas as pd
    df = load(base).assign(source_dir=base)
    grid = set(map(tuple, df[RUN_ID[:2] + RUN_ID[3:]].values))     # (map, robots, seed)
    sources = [Source(base, read_provenance(base))]
    taken = {}
    parts = []
    for folder in replacements:
        rep = load(folder).assign(source_dir=folder)
        algs = sorted(rep["alg"].astype(str).unique())
        for a in algs:
            if a in taken:
                raise PatrolInputError(f"{folder}: algorithm {a} is already replaced by "
                                       f"{taken[a]}")
            mine, theirs = rep[rep["alg"] == a], df[df["alg"] == a]
            want = (set(map(tuple, theirs[RUN_ID].values)) if len(theirs)
                    else {(m, n, a, s) for m, n, s in grid})
            if set(map(tuple, mine[RUN_ID].values)) != want:
                raise PatrolInputError(f"{folder}: the runs of {a} are not the same maps, team "
                                       f"sizes and seeds as in {base}")
            ref = theirs if len(theirs) else df
            for c in config_columns(ref):
                if c in mine and (set(mine[c].astype(str)) != set(ref[c].astype(str))):
                    raise PatrolInputError(f"{folder}: setting {c} of {a} differs from {base}'s")
            taken[a] = folder
        parts.append(rep)
        sources.append(Source(folder, read_provenance(folder), algs))
    kept = df[~df["alg"].isin(list(taken))]
    sources[0].algs = sorted(kept["alg"].astype(str).unique())
    merged = pd.concat([kept] + parts, ignore_index=True) if parts else df
    return merged, sources


def display_names(df) -> Dict[str, str]:
    """{alg: the name the tables print}: the reports' name
    (:func:`patrolling_sim.algorithms.base.display_name`, e.g. ``POLICY slots_bc@e6a12886``,
    the policy file's label recorded in the run's info.csv), from the first run of the
    algorithm that ended on ``TIMEOUT`` and whose info.csv is found (under its campaign
    folder, column ``source_dir``, or as given); else the short name."""
    out = {}
    for alg, g in df[df["status"] == "TIMEOUT"].groupby("alg"):
        params = next((p for p in map(_algorithm_params, g.head(3).to_dict("records"))
                       if p is not None), None)
        out[str(alg)] = str(alg) if params is None else display_name(str(alg), params)
    return out


def _algorithm_params(run) -> Optional[str]:
    """info.csv's ``algorithm_params`` of one runs.csv row (a dict), or None if its info.csv
    is not found (under ``source_dir``, or at ``prefix`` as given) or not readable."""
    prefix = str(run.get("prefix", ""))
    for path in (os.path.join(str(run.get("source_dir", "")), prefix + "_info.csv"),
                 prefix + "_info.csv"):
        try:
            with open(path, encoding="utf-8") as f:
                return parse_info_line(f.read(), path)["algorithm_params"]
        except (OSError, ValueError):
            continue
    return None
