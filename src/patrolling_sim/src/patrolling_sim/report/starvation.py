"""Starving cells of the reference tables: which cells they are and why.

Two kinds of cells are flagged:

- **never visited**: a run whose ``never_visited`` count (``docs/metrics.md``) is above zero
  left some vertex without a single visit for its whole duration; its worst idleness is then
  the run's length, not an interval anyone measured ("a vertex was never visited in k of n
  seeds");
- **rises with the team**: the cell's mean worst idleness is over :data:`RISE` times the
  lowest of the same map and algorithm with fewer robots (more robots patrol worse).

The tables give the cause of each flagged cell, read from a *causes file*: a YAML list of
entries

.. code-block:: yaml

    - alg: DTAP                       # one algorithm's short name
      maps: [1r5, ctcv]               # or "all"
      robots: [6, 8, 12]              # or "all"
      cause: one or two sentences     # the mechanism
      link: algorithms/DTAP.md#where-it-starves-a-vertex   # optional, relative to docs/

The first entry that matches a cell (algorithm, map, team size) explains it. A flagged cell
that no entry matches is printed with "cause not documented", and counted as such in the
index, so that a reader never takes a starving cell for a measured idleness.
"""
from dataclasses import dataclass
from typing import List, Optional, Sequence, Union

import yaml

from patrolling_sim.common.errors import PatrolInputError

ALL = "all"
#: a cell's worst idleness "rises with the team" above this factor times a smaller team's
RISE = 1.5
_KEYS = {"alg", "maps", "robots", "cause", "link"}


@dataclass(frozen=True)
class Cause:
    """One entry of a causes file (module docstring)."""
    alg: str
    maps: Union[str, Sequence[str]]
    robots: Union[str, Sequence[int]]
    cause: str
    link: Optional[str] = None

    def matches(self, alg: str, map_name: str, robots: int) -> bool:
        """True if this entry explains the cell (``alg``, ``map_name``, ``robots``)."""
        return (alg == self.alg and (self.maps == ALL or map_name in self.maps)
                and (self.robots == ALL or int(robots) in self.robots))


def load_causes(path: Optional[str]) -> List[Cause]:
    """The entries of the causes file ``path`` (an empty list for None).

    Raises:
        PatrolInputError: one line naming the file and the entry, for a missing or
            unreadable file, bad YAML, or an entry with a missing, unknown or ill-typed key.
    """
    if path is None:
        return []
    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except OSError as e:
        raise PatrolInputError(f"{path}: cannot read causes file ({e.strerror})")
    except yaml.YAMLError as e:
        raise PatrolInputError(f"{path}: bad YAML ({str(e).splitlines()[0]})")
    if not isinstance(data, list):
        raise PatrolInputError(f"{path}: expected a list of entries (alg, maps, robots, cause)")
    return [_entry(path, k, e) for k, e in enumerate(data, 1)]


def _entry(path, k, e) -> Cause:
    where = f"{path}: entry {k}"
    if not isinstance(e, dict):
        raise PatrolInputError(f"{where}: expected a mapping")
    unknown = sorted(set(e) - _KEYS)
    missing = sorted({"alg", "maps", "robots", "cause"} - set(e))
    if unknown or missing:
        what = (f"unknown key(s) {', '.join(unknown)}" if unknown
                else f"missing key(s) {', '.join(missing)}")
        raise PatrolInputError(f"{where}: {what}")
    if not isinstance(e["alg"], str) or not isinstance(e["cause"], str) or not e["cause"]:
        raise PatrolInputError(f"{where}: alg and cause must be non-empty text")
    maps, robots = e["maps"], e["robots"]
    if maps != ALL and not (isinstance(maps, list) and all(isinstance(m, str) for m in maps)):
        raise PatrolInputError(f"{where}: maps must be 'all' or a list of map names")
    if robots != ALL and not (isinstance(robots, list)
                              and all(isinstance(n, int) and n > 0 for n in robots)):
        raise PatrolInputError(f"{where}: robots must be 'all' or a list of team sizes")
    link = e.get("link")
    if link is not None and not isinstance(link, str):
        raise PatrolInputError(f"{where}: link must be text")
    return Cause(e["alg"], maps if maps == ALL else tuple(maps),
                 robots if robots == ALL else tuple(robots), e["cause"].strip(), link)


def cause_of(causes: Sequence[Cause], alg: str, map_name: str, robots: int) -> Optional[Cause]:
    """The first entry of ``causes`` that explains the cell, or None."""
    return next((c for c in causes if c.matches(alg, map_name, robots)), None)


def flag_text(starved: int, n: int, most: int) -> str:
    """The table's flag for a cell: ``starved`` of ``n`` seeds left up to ``most`` vertices
    unvisited ("" when none did)."""
    if not starved:
        return ""
    return f"{starved} of {n} (up to {most})"


def note_line(alg: str, starved: int, n: int, duration, cause: Optional[Cause],
              docs_prefix: str = "../") -> str:
    """The sentence printed under a table for a flagged cell; ``docs_prefix`` turns the
    entry's link (relative to docs/) into one relative to the page."""
    d = f"{float(duration):g} s" if duration == duration else "the run"
    head = (f"- **{alg}**: in {starved} of {n} seeds some vertex was never visited in "
            f"{d}; its worst idleness there is the run's length, not a measured interval. ")
    return head + _cause_text(cause, docs_prefix)


def mark_rises(stats):
    """Add to ``stats`` (one row per map, robots, alg, with ``worst_idleness_mean``) the
    columns ``rise_from`` (the smaller team whose worst idleness is the lowest, or 0) and
    ``rise_worst`` (that worst idleness) for the cells whose worst idleness is over
    :data:`RISE` times it; 0 and NaN elsewhere. Returns ``stats``."""
    stats["rise_from"] = 0
    stats["rise_worst"] = float("nan")
    for _, g in stats.groupby(["map", "alg"]):
        best_n, best = 0, float("inf")
        for i, r in g.sort_values("robots").iterrows():
            w = r["worst_idleness_mean"]
            if w == w and best_n and w > RISE * best:
                stats.loc[i, "rise_from"] = best_n
                stats.loc[i, "rise_worst"] = best
            if w == w and w < best:
                best_n, best = int(r["robots"]), w
    return stats


def rise_line(alg: str, worst: float, smaller: int, smaller_worst: float,
              cause: Optional[Cause], docs_prefix: str = "../") -> str:
    """The sentence printed under a table for a cell whose worst idleness rises with the
    team: ``worst`` against ``smaller_worst`` with ``smaller`` robots."""
    head = (f"- **{alg}** (↑): its worst idleness, {worst:.0f} s, is "
            f"{worst / smaller_worst:.1f} times that of {smaller} "
            f"robot{'s' if smaller > 1 else ''} on this map ({smaller_worst:.0f} s). ")
    return head + _cause_text(cause, docs_prefix)


def _cause_text(cause, docs_prefix):
    if cause is None:
        return "Cause: **not documented**."
    link = f" ([more]({docs_prefix}{cause.link}))" if cause.link else ""
    return f"Cause: {cause.cause}{link}"


def index_section(stats, causes) -> List[str]:
    """The index's list of flagged cells (empty when there is none), with the count of
    those without a documented cause."""
    flagged = stats[(stats["starved"] > 0) | (stats["rise_from"] > 0)]
    if flagged.empty:
        return []
    rows, undocumented = [], 0
    for _, r in flagged.sort_values(["map", "alg", "robots"]).iterrows():
        c = cause_of(causes, r["alg"], r["map"], int(r["robots"]))
        undocumented += c is None
        why = "**not documented**" if c is None else (
            f"[documented](../{c.link})" if c.link else "documented (on the map's page)")
        kinds = []
        if r["starved"]:
            kinds.append(f"never visited: {r['starved']} of {r['n']} seeds, up to "
                         f"{r['starved_most']} vertices")
        if r["rise_from"]:
            k = int(r["rise_from"])
            kinds.append(f"↑ worst idleness {r['worst_idleness_mean'] / r['rise_worst']:.1f}x "
                         f"that of {k} robot{'s' if k > 1 else ''}")
        rows.append(f"| [{r['map']}]({r['map']}.md) | {r['robots']} | {r['alg']} | "
                    f"{'; '.join(kinds)} | {why} |")
    return ["", "## Flagged cells", "",
            f"{len(flagged)} cells are flagged ({undocumented} without a documented cause): "
            "a seed in which some vertex got no visit in the whole run (the cell's worst "
            "idleness is then the run's length, marked ≥), or a worst idleness over "
            f"{RISE:g} times that of a smaller team on the same map (marked ↑). Each map's "
            "page gives the cause under the table.", "",
            "| map | robots | algorithm | flag | cause |", "|---|---|---|---|---|"] + rows
