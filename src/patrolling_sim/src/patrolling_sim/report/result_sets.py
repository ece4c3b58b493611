"""The result sets a report finds under its inputs: runs with an info file, runs with only a
``_run.yaml`` (the monitor wrote no info file), and how an unusable one is shown."""
import math
import os
from dataclasses import dataclass

from patrolling_sim.common.errors import PatrolInputError

INFO_SUFFIX = "_info.csv"
RUN_YAML_SUFFIX = "_run.yaml"
IDLENESS_SUFFIX = "_idleness.csv"


#: the status a report gives a result set it could not read (never a run's own status)
UNREADABLE = "UNREADABLE"


class UnreadableRun:
    """A result set a report could not use (:func:`load_runs`' ``unreadable``), shaped like a
    :class:`Run` for the excluded-runs table: status :data:`UNREADABLE`, and the map, team
    size and algorithm read from its path (``<map>_<N>/<ALG>/<host>/<date>``) when it
    follows the results tree."""

    def __init__(self, prefix):
        self.prefix = prefix
        parts = prefix.replace(os.sep, "/").split("/")
        group, alg = (parts[-4], parts[-3]) if len(parts) >= 4 else ("", "")
        map_name, _, n = group.rpartition("_")
        self.info = {"map": map_name or "?", "team_size": int(n) if n.isdigit() else -1,
                     "algorithm": alg or "?", "sim_duration": math.nan}
        self.status = UNREADABLE
        self.status_note = ""
        self.run_id = "/".join(parts[-4:])


@dataclass
class ResultSets:
    """What :func:`find_result_sets` found: ``prefixes`` of runs with an info file (sorted,
    de-duplicated by real path), ``unfinished`` prefixes with a ``_run.yaml`` and no info
    file, and ``warnings`` (one line per idleness file with neither)."""
    prefixes: list
    unfinished: list
    warnings: list


def find_result_sets(dirs):
    """Every run's result set under ``dirs`` (:class:`ResultSets`).

    Raises:
        PatrolInputError: a path that does not exist, or no results under any of them.
    """
    prefixes = {}
    orphans = []
    unfinished = []                 # a _run.yaml without an info.csv
    for d in dirs:
        if not os.path.exists(d):
            raise PatrolInputError(f"argument RESULTS_DIR: '{d}' does not exist")
        if os.path.isfile(d):
            if d.endswith(INFO_SUFFIX):
                candidates = [(os.path.dirname(d) or ".", [], [os.path.basename(d)])]
            elif d.endswith(RUN_YAML_SUFFIX):           # a run record: its info file if any
                stem = d[: -len(RUN_YAML_SUFFIX)]
                if os.path.isfile(stem + INFO_SUFFIX):
                    prefixes.setdefault(os.path.realpath(stem), stem)
                else:
                    unfinished.append(stem)
                continue
            else:
                raise PatrolInputError(f"argument RESULTS_DIR: '{d}' is a file but not a "
                                       f"*{INFO_SUFFIX} or *{RUN_YAML_SUFFIX} file")
        else:
            candidates = os.walk(d, onerror=None, followlinks=False)
        found_here = 0
        for root, _dirs, files in candidates:
            names = set(files)
            for name in files:
                if name.endswith(INFO_SUFFIX):
                    p = os.path.join(root, name[: -len(INFO_SUFFIX)])
                    prefixes.setdefault(os.path.realpath(p), p)
                    found_here += 1
                elif name.endswith(IDLENESS_SUFFIX):
                    stem = name[: -len(IDLENESS_SUFFIX)]
                    if stem + INFO_SUFFIX not in names:
                        orphans.append(os.path.join(root, name))
                elif name.endswith(RUN_YAML_SUFFIX):
                    stem = name[: -len(RUN_YAML_SUFFIX)]
                    if stem + INFO_SUFFIX not in names:
                        unfinished.append(os.path.join(root, stem))
        if not found_here and not any(o.startswith(os.path.join(d, "")) or o == d
                                      for o in orphans):
            raise PatrolInputError(f"argument RESULTS_DIR: '{d}' holds no results "
                                   f"(no *{INFO_SUFFIX} file)")
    with_record = {u + IDLENESS_SUFFIX for u in unfinished}
    warnings = [f"{o}: no matching {INFO_SUFFIX} (run did not finish?): skipped"
                for o in sorted(set(orphans) - with_record)]
    if not prefixes:
        raise PatrolInputError("argument RESULTS_DIR: no finished run (no *_info.csv file) in "
                               + ", ".join(f"'{d}'" for d in dirs))
    return ResultSets(sorted(prefixes.values()), sorted(set(unfinished)), warnings)
