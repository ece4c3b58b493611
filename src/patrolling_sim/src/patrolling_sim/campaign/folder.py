"""A campaign owns its folder: one campaign command at a time holds it (an advisory lock the
kernel releases on any exit), and a folder that holds another campaign is refused unless the
user asks for a new one.

    with hold_folder(out, campaign, force_new=False):
        run_campaign(campaign, out)
"""
import contextlib
import datetime
import fcntl
import os
import socket

import yaml

from patrolling_sim.campaign.spec import Campaign
from patrolling_sim.common.errors import PatrolInputError

#: the lock file inside a campaign folder (it stays; holding it is what counts)
LOCK_FILE = ".campaign.lock"
#: the campaign file as the folder's campaign read it (written by the engine)
CAMPAIGN_FILE = "campaign.yaml"


def _holder(fd):
    """The holder's line written in the lock file (pid, host, start), or "unknown"."""
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        return os.read(fd, 4096).decode("utf-8", "replace").strip() or "unknown"
    except OSError:
        return "unknown"


def lock_folder(out):
    """Take the campaign folder ``out`` (made if missing) for this process: returns the open
    lock file's descriptor, held until it is closed or the process ends however it ends.

    Raises:
        PatrolInputError: another process holds the folder (the message names it), or the
        folder cannot be made or written.
    """
    try:
        os.makedirs(out, exist_ok=True)
        fd = os.open(os.path.join(out, LOCK_FILE), os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as e:
        raise PatrolInputError(f"argument --out: cannot use '{out}' ({e.strerror})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _holder(fd)
        os.close(fd)
        raise PatrolInputError(f"argument --out: '{out}' is in use by another campaign "
                               f"({holder}): wait for it to end, or choose another --out"
                               ) from None
    stamp = datetime.datetime.now().isoformat(timespec="seconds")
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()} since {stamp}\n".encode(), 0)
    return fd


def check_owner(out, campaign: Campaign, force_new=False):
    """Refuse a folder that holds another campaign: its ``campaign.yaml`` differs from
    ``campaign``'s file (as parsed). With ``force_new`` the folder is taken over: the new
    campaign's table and report use only its own runs' records, whatever lies in the folder.

    Raises:
        PatrolInputError: the folder holds another campaign and ``force_new`` is false.
    """
    path = os.path.join(out, CAMPAIGN_FILE)
    if force_new or not os.path.isfile(path):
        return
    try:
        with open(path, encoding="utf-8") as f:
            theirs = yaml.safe_load(f)
    except (OSError, yaml.YAMLError):
        theirs = None
    if theirs != campaign.raw:
        name = theirs.get("name") if isinstance(theirs, dict) else None
        raise PatrolInputError(
            f"argument --out: '{out}' holds another campaign"
            + (f" ('{name}')" if name else "") + " (its campaign.yaml differs from this "
            "file): choose another --out, or give --force-new to start this campaign there")


@contextlib.contextmanager
def hold_folder(out, campaign: Campaign, force_new=False):
    """Hold the campaign folder ``out`` for ``campaign`` while the ``with`` block runs
    (:func:`lock_folder`, then :func:`check_owner`); released on leaving it.

    Raises:
        PatrolInputError: as :func:`lock_folder` and :func:`check_owner`.
    """
    fd = lock_folder(out)
    try:
        check_owner(out, campaign, force_new)
        yield out
    finally:
        os.close(fd)
