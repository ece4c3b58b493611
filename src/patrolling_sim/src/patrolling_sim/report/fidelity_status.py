"""How each cell of the reference tables compares with the original's own agents.

The fidelity matrix (``bench/fidelity_matrix.py``, ``docs/fidelity_matrix.md``) compares, per
map, team size and algorithm, runs of the original's agents with this project's graph mode;
with ``--status FILE`` it also writes one CSV row per cell::

    map,robots,alg,status,detail
    1r5,2,DTAP,within,-2% / -6% / +3%

``status`` is one of :data:`STATUSES`: ``within`` (every metric within tolerance), ``known``
(the metrics outside it are documented differences), ``differs`` (not documented). The
reference tables read this file (``scripts/reference_docs.py --fidelity FILE``) and link each
measured cell's status to the matrix.
"""
import csv
from typing import Dict, Optional, Tuple

from patrolling_sim.common.errors import PatrolInputError

STATUSES = ("within", "known", "differs")
#: where a reference page's status cell links to (relative to docs/reference/)
MATRIX_LINK = "../fidelity_matrix.md"
COLUMNS = ("map", "robots", "alg", "status", "detail")
#: (map, robots, alg) -> (status, detail)
Status = Dict[Tuple[str, int, str], Tuple[str, str]]


def load_status(path: Optional[str]) -> Status:
    """The cells of a fidelity status file (empty for None).

    Raises:
        PatrolInputError: one line naming the file and the row, for a missing or unreadable
            file, missing columns, a team size that is not a positive integer, an unknown
            status or a cell given twice.
    """
    if path is None:
        return {}
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            rows = list(reader)
            header = reader.fieldnames or []
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise PatrolInputError(f"{path}: cannot read the fidelity status file ({e})")
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise PatrolInputError(f"{path}: missing column(s) {', '.join(missing)}")
    out: Status = {}
    for i, r in enumerate(rows, start=2):
        try:
            n = int(r["robots"])
            if n < 1:
                raise ValueError
        except (TypeError, ValueError):
            raise PatrolInputError(f"{path}: line {i}: robots must be a positive integer, got "
                                   f"{r['robots']!r}")
        if r["status"] not in STATUSES:
            raise PatrolInputError(f"{path}: line {i}: status must be one of "
                                   f"{', '.join(STATUSES)}, got {r['status']!r}")
        key = (r["map"], n, r["alg"])
        if key in out:
            raise PatrolInputError(f"{path}: line {i}: {r['map']} {n} {r['alg']} given twice")
        out[key] = (r["status"], r["detail"] or "")
    return out


def write_status(path: str, rows) -> None:
    """Write ``rows`` (map, robots, alg, status, detail) as a status file."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(COLUMNS)
        w.writerows(rows)


def cell_text(status: Status, map_name: str, robots: int, alg: str, link: str) -> str:
    """The table cell for one (map, robots, alg): the status linked to ``link``, or empty
    when the cell was not measured against the original."""
    s = status.get((map_name, int(robots), alg))
    return f"[{s[0]}]({link})" if s else ""
