"""The reference tables' column "vs original" brought up to date without their campaign.

The fidelity matrix grows (more runs of the original's own agents) while the reference
campaign stays the same; :func:`relinked_files` rewrites only that column of the pages
:mod:`patrolling_sim.report.reference_docs` wrote, from a newer status file
(:mod:`patrolling_sim.report.fidelity_status`): byte for byte what a full rebuild with that
file writes, plus one line in the index saying when.
"""
import datetime
import os
import re
from typing import Dict

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.report import fidelity_status

_ROBOTS_HEADING = re.compile(r"^## (\d+) robots?$")
#: the line of the index that says when the column "vs original" was last relinked
RELINK_MARK = "The column \"vs original\" was relinked"


def relink_fidelity(text: str, map_name: str, fidelity,
                    link: str = fidelity_status.MATRIX_LINK) -> str:
    """A map page (``text``, as
    :func:`patrolling_sim.report.reference_docs.build_reference_docs` wrote it with a
    fidelity file) whose column "vs original" says what ``fidelity`` (a loaded status,
    :func:`patrolling_sim.report.fidelity_status.load_status`) says now; every other
    character is kept. The matrix grows without the campaign changing, so the links can be
    brought up to date without the campaign's runs.

    Raises:
        PatrolInputError: the page has no table with a column "vs original".
    """
    out, robots, in_table, tables = [], None, False, 0
    for line in text.split("\n"):
        m = _ROBOTS_HEADING.match(line)
        if m:
            robots, in_table = int(m.group(1)), False
        elif line.startswith("| algorithm |"):
            in_table = line.endswith(" vs original |")
            tables += in_table
        elif in_table and line.startswith("| ") and robots is not None:
            cells = line.split("|")
            name = cells[1].strip()
            if name and not name.startswith("*"):      # not a reference row
                text_ = fidelity_status.cell_text(fidelity, map_name, robots, name.split()[0],
                                                  link)
                cells[-2] = f" {text_} "
                line = "|".join(cells)
        elif not line.startswith("|"):
            in_table = False
        out.append(line)
    if not tables:
        raise PatrolInputError(f"{map_name}: the page has no column 'vs original' (made "
                               "without --fidelity)")
    return "\n".join(out)


def relinked_files(folder: str, fidelity_file: str, now=None) -> Dict[str, str]:
    """{file name: new content} for every map page under ``folder`` (the pages
    :func:`patrolling_sim.report.reference_docs.write_docs` wrote) and its ``README.md``
    index: each page relinked to ``fidelity_file`` (:func:`relink_fidelity`), the index with
    one line saying when. Nothing is written.

    Raises:
        PatrolInputError: one line, for a folder without reference pages, a bad status file or
            a page without the column.
    """
    fidelity = fidelity_status.load_status(fidelity_file)
    index = os.path.join(folder, "README.md")
    if not os.path.isfile(index):
        raise PatrolInputError(f"{folder}: no reference tables here (no README.md)")
    with open(index, encoding="utf-8") as f:
        maps = re.findall(r"^\| \[([^\]]+)\]\(\1\.md\) \|", f.read(), flags=re.M)
    if not maps:
        raise PatrolInputError(f"{index}: lists no map page")
    files = {}
    for m in maps:
        path = os.path.join(folder, f"{m}.md")
        try:
            with open(path, encoding="utf-8") as f:
                files[f"{m}.md"] = relink_fidelity(f.read(), m, fidelity)
        except OSError as e:
            raise PatrolInputError(f"{path}: cannot read the page ({e.strerror})")
    now = now or datetime.datetime.now(datetime.timezone.utc)
    with open(index, encoding="utf-8") as f:
        lines = [ln for ln in f.read().rstrip("\n").split("\n")
                 if not ln.startswith(RELINK_MARK)]
    lines += ["", f"{RELINK_MARK} to `{fidelity_file}` on {now.strftime('%Y-%m-%d %H:%M UTC')} "
              "(`scripts/reference_docs.py --relink " + folder + " --fidelity "
              + fidelity_file + "`): the runs and their figures are those above."]
    kept = [ln for i, ln in enumerate(lines) if ln or not (i and lines[i - 1] == "")]
    files["README.md"] = "\n".join(kept) + "\n"
    return files
