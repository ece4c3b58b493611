"""A full disk on demand: run a command in a mount namespace of its own (``unshare``) where a
folder is a tmpfs of a few kilobytes, so that writing results there fails with ENOSPC. The
namespace (and the tmpfs) ends with the command; nothing on the machine is mounted. Before it
ends, every temporary file left in the folder is printed on stdout as ``LEFTOVER <path>``."""
import os
import shlex
import shutil
import subprocess

import pytest


def small_fs_argv(folder, size, argv):
    """The argv that runs ``argv`` with ``folder`` (created if missing) a tmpfs of ``size``
    (e.g. "40k"), as root of a new user and mount namespace; its exit status is the
    command's."""
    os.makedirs(folder, exist_ok=True)
    q = shlex.quote(str(folder))
    inner = (f"mount -t tmpfs -o size={size} tmpfs {q} || exit 99; {shlex.join(argv)}; "
             f"rc=$?; find {q} -name '*.tmp*' -printf 'LEFTOVER %p\\n'; exit $rc")
    return ["unshare", "--map-root-user", "--mount", "sh", "-c", inner]


def require_small_fs(tmp_path):
    """Skip the test where this machine allows no mount namespace (a container without the
    capability): the full disk cannot be made there."""
    if shutil.which("unshare") is None:
        pytest.skip("no unshare(1) on this machine")
    probe = subprocess.run(small_fs_argv(tmp_path / "probe", "8k", ["true"]),
                           capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {probe.stderr.strip()}")


def leftovers(folder):
    """Temporary files left under ``folder`` (``*.tmp*``)."""
    return [os.path.join(d, f) for d, _, files in os.walk(folder) for f in files
            if ".tmp" in f]


def reported_leftovers(stdout):
    """The temporary files the command of :func:`small_fs_argv` left in the small folder."""
    return [ln[len("LEFTOVER "):] for ln in stdout.splitlines() if ln.startswith("LEFTOVER ")]
