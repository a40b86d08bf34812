"""Output folders and result files of the commands: checked before any work, written atomically.

Every command that writes results (``dss14 bench``, ``dss14 train``, ``dss14 reproduce``, the
campaigns) owns a set of files in its output folder.  :func:`prepare_output_dir` runs before
any work: it refuses a path that is a file, a folder that cannot be created or written, and a
folder that already holds results of the command unless ``overwrite`` is given -- then it
removes exactly the files and folders the command owns (nothing else), so a new run's results
are never mixed with an old run's.  :func:`atomic_write_text` and :func:`atomic_write_bytes`
write a file through a temporary file in the same folder and an atomic rename, so an
interrupted run never leaves a half-written result file.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp()) / "out"
>>> prepare_output_dir(d, owned=("results.json",)) == d
True
>>> atomic_write_text(d / "results.json", "{}")
>>> prepare_output_dir(d, owned=("results.json",))
Traceback (most recent call last):
...
dss14_env.core.outdir.OutputDirError: output folder ... already holds results (results.json); ...
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path


class OutputDirError(ValueError):
    """An output folder that cannot be used; the message is one line naming the path."""


def _owned_present(path: Path, owned: Iterable[str]) -> list[str]:
    out = []
    for pattern in owned:
        out += sorted(p.name for p in path.glob(pattern))
    return out


def prepare_output_dir(path: str | os.PathLike, owned: Iterable[str], overwrite: bool = False,
                       option: str = "--out") -> Path:
    """Check (and create) an output folder before a command does any work.

    :param path: the folder
    :param owned: names or glob patterns of the files and folders the command writes there
    :param overwrite: remove what the command owns instead of refusing
    :param option: the command-line option that named the folder (for the message)
    :return: the folder, created, writable, holding none of the command's files
    :raises OutputDirError: a file in the way, a folder that cannot be created or written, or
        earlier results without ``overwrite``
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputDirError(f"{option} {p}: is a file, not a folder")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputDirError(f"{option} {p}: cannot create the folder ({exc.strerror or exc})") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".write-test-", dir=p)
    except OSError as exc:
        raise OutputDirError(f"{option} {p}: folder is not writable ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)
    owned = tuple(owned)
    present = _owned_present(p, owned)
    if present:
        if not overwrite:
            shown = ", ".join(present[:5]) + (", ..." if len(present) > 5 else "")
            raise OutputDirError(f"output folder {p} already holds results ({shown}); pass "
                                 f"--overwrite to replace them, or choose another folder")
        for pattern in owned:
            for q in p.glob(pattern):
                if q.is_dir() and not q.is_symlink():
                    shutil.rmtree(q)
                else:
                    q.unlink()
    return p


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and an atomic rename."""
    p = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; results are ordinary files
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically (:func:`atomic_write_bytes`)."""
    atomic_write_bytes(path, text.encode("utf-8"))
