"""DTA ``.params`` files (DTAGreedy.params, DTASSI.params).

Layout: ``[SECTION Main]`` naming ``PROFILE <name>``, then ``[PROFILE <name>]`` with
``key value`` lines until ``[END]``. Lines starting with ``#``, ``;`` or ``/`` are comments;
double-quoted values may contain spaces; keys absent from the file read as 0.
"""
import shlex

from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.textfile import read_text


def load_dta_params(path, defaults=None):
    """Return ``{key: value}`` of the active profile; numeric values become floats.

    Raises:
        PatrolInputError: missing file, no profile, or a malformed line.
    """
    lines = read_text(path, "DTA params file").splitlines()
    sections = {}
    current = None
    for lineno, raw in enumerate(lines, 1):
        line = raw.strip()
        if not line or line[0] in "#;/":
            continue
        if line.startswith("[") and line.endswith("]"):
            head = line[1:-1].split()
            if head == ["END"]:
                current = None
            elif len(head) == 2 and head[0] in ("SECTION", "PROFILE"):
                current = sections.setdefault(f"{head[0]} {head[1]}", {})
            else:
                raise PatrolInputError(f"{path}:{lineno}: unknown header '{line}'")
            continue
        if current is None:
            raise PatrolInputError(f"{path}:{lineno}: '{line}' outside a [SECTION]/[PROFILE]")
        try:
            parts = shlex.split(line)
        except ValueError:
            raise PatrolInputError(f"{path}:{lineno}: unbalanced quotes in '{line}'") from None
        if len(parts) != 2:
            raise PatrolInputError(f"{path}:{lineno}: expected 'key value', got '{line}'")
        key, value = parts
        try:
            current[key] = float(value)
        except ValueError:
            current[key] = value
    main = sections.get("SECTION Main")
    if main is None or "PROFILE" not in main:
        raise PatrolInputError(f"{path}: no [SECTION Main] naming a PROFILE")
    profile = sections.get(f"PROFILE {main['PROFILE']}")
    if profile is None:
        raise PatrolInputError(f"{path}: profile '{main['PROFILE']}' is not defined")
    out = dict(defaults or {})
    out.update(profile)
    return out
