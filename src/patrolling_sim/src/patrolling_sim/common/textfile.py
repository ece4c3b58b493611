"""Reading an input text or YAML file with the project's one-line errors: ``<path>: <what>
not found``, ``<path>: cannot read <what> (<reason>)``, ``<path>[:line]: invalid YAML``.
Used by the loaders of batches, DTA parameters, MSP routes and initial poses; also the YAML
emitter and loader of records written and read in bulk, and the atomic writer of small
files (:func:`write_atomic`)."""
import os

import yaml

from patrolling_sim.common.errors import PatrolInputError


def read_text(path, what):
    """The whole UTF-8 text of ``path``; ``what`` names the file in errors ("batch file")."""
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except FileNotFoundError:
        raise PatrolInputError(f"{path}: {what} not found") from None
    except (OSError, UnicodeDecodeError) as e:
        reason = getattr(e, "strerror", None) or e.__class__.__name__
        raise PatrolInputError(f"{path}: cannot read {what} ({reason})") from None


def read_yaml(path, what):
    """The YAML document of ``path`` (``yaml.safe_load``), errors as :func:`read_text` and
    ``<path>[:line]: invalid YAML``."""
    text = read_text(path, what)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f":{mark.line + 1}" if mark else ""
        raise PatrolInputError(f"{path}{where}: invalid YAML") from None


#: LibYAML's safe emitter when PyYAML has it (Debian's does), else PyYAML's own
YamlDumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
#: LibYAML's safe loader when PyYAML has it, else PyYAML's own
YamlLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def write_atomic(path, text):
    """Write ``text`` (UTF-8) to ``path`` atomically: into a temporary file beside it, then
    renamed into place. On any failure (a full disk included) the temporary file is removed
    and the error raised: ``path`` keeps its old content, nothing half-written is left.
    Returns ``path``."""
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(e, OSError) and e.filename == tmp:
            e.filename = path          # name the file the caller asked for
        raise
    return path
