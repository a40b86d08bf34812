"""A lock on an output folder in use: one run writes into a folder at a time.

:func:`lock_folder` takes an advisory ``flock`` on :data:`LOCK_FILE` inside the folder and
writes the holder (process id, host, command, start time) into it; a second run that asks for
the same folder gets :class:`FolderInUseError` naming the folder and the holder.  The kernel
drops the lock when the holder's process ends, however it ends (a crash, SIGKILL), so a lock
file a dead run left behind is taken over by the next run without any guessing from process
ids; :func:`unlock_folder` removes the file and drops the lock when the run ends.

The file is removed while the lock is held and a new holder checks, after locking, that the
file it locked is still the one in the folder, so two runs that race for a stale lock file
never both hold it.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> lock_folder(d, "bench")
>>> folder_locked(d)
True
>>> unlock_folder(d)
>>> folder_locked(d), (d / LOCK_FILE).exists()
(False, False)
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path

#: the lock file of a folder in use (its holder, one JSON line)
LOCK_FILE = ".dss14_lock"
#: the most bytes of a lock file read for the message
_HOLDER_BYTES = 4096

#: the folders this process holds: resolved path -> the open lock file
_HELD: dict[str, int] = {}


class FolderInUseError(ValueError):
    """An output folder another run is writing into; the message names both."""


def _key(folder: str | os.PathLike) -> str:
    return str(Path(folder).resolve())


def folder_locked(folder: str | os.PathLike) -> bool:
    """Whether this process holds the lock on ``folder``."""
    return _key(folder) in _HELD


def held_root(path: str | os.PathLike) -> Path | None:
    """The deepest folder this process holds that contains ``path`` (resolved), or None."""
    if not _HELD:
        return None
    q = Path(path)
    q = q.parent.resolve() / q.name
    for f in (q, *q.parents):
        if str(f) in _HELD:
            return f
    return None


def _holder(fd: int) -> str:
    """The holder a lock file names, in words."""
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        data = json.loads(os.read(fd, _HOLDER_BYTES).decode("utf-8", "replace"))
        return (f"'{data['command']}', process {int(data['pid'])} on {data['host']}, "
                f"since {data['started_utc']}")
    except (OSError, ValueError, KeyError, TypeError):
        return "a run that left no record of itself"


def lock_folder(folder: str | os.PathLike, command: str, option: str = "--out") -> None:
    """Take the lock on ``folder`` (an existing folder) for this process's run ``command``
    (nothing when it holds it already).

    :raises FolderInUseError: another run holds it (the message names the folder and the run)
    """
    key = _key(folder)
    if key in _HELD:
        return
    path = Path(key) / LOCK_FILE
    for _ in range(8):  # a file removed by its holder between our open and our lock: again
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            who = _holder(fd)
            os.close(fd)
            raise FolderInUseError(f"{option} {folder}: is in use by another run ({who}); wait "
                                   f"for it to end, or choose another folder") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    else:  # pragma: no cover - a folder whose lock file is replaced again and again
        raise FolderInUseError(f"{option} {folder}: its lock file {LOCK_FILE} keeps changing; "
                               f"choose another folder")
    record = {"pid": os.getpid(), "host": socket.gethostname(), "command": command,
              "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    os.ftruncate(fd, 0)
    os.pwrite(fd, (json.dumps(record) + "\n").encode("utf-8"), 0)
    _HELD[key] = fd


def unlock_folder(folder: str | os.PathLike) -> None:
    """Drop this process's locks on ``folder`` and on the folders inside it (a run's nested
    runs end with it) and remove their lock files (nothing when it holds none).
    """
    top = Path(_key(folder))
    for key in [k for k in _HELD if Path(k) == top or top in Path(k).parents]:
        fd = _HELD.pop(key)
        with contextlib.suppress(OSError):
            os.unlink(Path(key) / LOCK_FILE)
        os.close(fd)


@contextlib.contextmanager
def folder_free(folder: str | os.PathLike, command: str, option: str = "--out") -> Iterator[None]:
    """Context manager: check that no other run holds ``folder`` (taking the lock for the block
    when this process does not hold it already).

    :raises FolderInUseError: another run holds it
    """
    held = folder_locked(folder)
    lock_folder(folder, command, option)
    try:
        yield
    finally:
        if not held:
            unlock_folder(folder)
