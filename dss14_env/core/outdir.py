"""Output folders and result files of the commands: checked before any work, written atomically.

Every command that writes results (``dss14 bench``, ``dss14 train``, ``dss14 reproduce``, the
campaigns) owns a set of names in its output folder (exact names or glob patterns).
:func:`prepare_output_dir` runs before any work: it refuses a path that is a file, a folder
that cannot be created or written, and a folder that already holds results of the command
unless ``overwrite`` is given.

Every run writes a **manifest**, :data:`MANIFEST` (``dss14_manifest.json``), beside its
results: the files it wrote.  ``overwrite`` removes exactly the files a manifest in the
folder lists (and folders they leave empty) -- never a file no run wrote: a user's files in
the folder survive.  A file of the user's where the run would write (an owned exact name, or
anything inside an owned folder) is refused before anything is removed, naming it.  The
manifest is written when the folder is claimed (:func:`prepare_output_dir`, no files yet) and
brought up to date by :func:`update_manifest` (every command calls it when it ends, however it
ends, and a training run at each checkpoint): it lists the files under the owned names that
were written since the folder was claimed.

:func:`atomic_write_text` and :func:`atomic_write_bytes` write a file through a temporary
file in the same folder and an atomic rename, so an interrupted run never leaves a
half-written result file; :func:`atomic_folder` does the same for a whole folder.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp()) / "out"
>>> prepare_output_dir(d, owned=("results.json",)) == d
True
>>> atomic_write_text(d / "results.json", "{}")
>>> update_manifest(d)
['results.json']
>>> prepare_output_dir(d, owned=("results.json",))
Traceback (most recent call last):
...
dss14_env.core.outdir.OutputDirError: output folder ... already holds results (results.json); ...
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

#: the manifest file of a run: the files it wrote (``overwrite`` removes those, nothing else)
MANIFEST = "dss14_manifest.json"
#: the manifest's format tag
MANIFEST_FORMAT = "dss14-manifest-1"


class OutputDirError(ValueError):
    """An output folder that cannot be used; the message is one line naming the path."""


def _owned_entries(folder: Path, owned: Iterable[str]) -> list[Path]:
    """The top-level entries of ``folder`` that match the owned names (sorted, unique)."""
    found: dict[str, Path] = {}
    for pattern in owned:
        for q in folder.glob(pattern):
            if q.name != MANIFEST:
                found[q.name] = q
    return [found[k] for k in sorted(found)]


def _files_under(entry: Path) -> list[Path]:
    """``entry`` itself (a file or link) or every file below it (links not followed)."""
    if entry.is_symlink() or not entry.is_dir():
        return [entry]
    out = []
    for root, dirs, files in os.walk(entry, followlinks=False):
        out += [Path(root) / f for f in files]
        out += [Path(root) / d for d in dirs if (Path(root) / d).is_symlink()]
    return out


def _read_manifest(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        return None
    return data


def _manifest_folders(folder: Path, owned: Iterable[str]) -> list[str]:
    """``folder`` and the folders below its owned entries that hold a manifest (a run's own,
    or a nested run's: a campaign's ``seed_<k>/``); nothing else of the folder is searched.
    """
    roots = [str(folder)] if (folder / MANIFEST).is_file() else []
    for e in _owned_entries(folder, owned):
        if e.is_dir() and not e.is_symlink():
            roots += [root for root, _, files in os.walk(e, followlinks=False) if MANIFEST in files]
    return roots


def _listed(folder: Path, owned: Iterable[str]) -> set[Path]:
    """The files of earlier runs under ``folder``'s owned names: every file a manifest there
    lists, the manifests themselves, and every file inside a folder a run owns (its
    ``checkpoints/``, ``chunks/``, ...) written after the run claimed the folder -- what a run
    killed between two manifest updates left there.  Paths are normalised, relative to the
    same base as ``folder``.
    """
    out: set[str] = set()
    for root in _manifest_folders(folder, owned):
        data = _read_manifest(Path(root) / MANIFEST)
        if data is None:
            continue
        out.add(os.path.join(root, MANIFEST))
        out.update(os.path.join(root, rel) for rel in data.get("files", [])
                   if isinstance(rel, str) and not os.path.isabs(rel))
        out.update(str(q) for q in _written_since_claim(Path(root), data, dirs_only=True))
    return {Path(os.path.normpath(q)) for q in out}


def _written_since_claim(root: Path, data: dict, dirs_only: bool = False) -> list[Path]:
    """The files under a manifest's owned names (only inside owned folders with ``dirs_only``)
    written since the run claimed ``root`` and not there before.
    """
    since = data.get("started_ns")
    if not isinstance(since, int):
        return []
    before = {x for x in data.get("preexisting", []) if isinstance(x, str)}
    out = []
    for e in _owned_entries(root, [o for o in data.get("owned", []) if isinstance(o, str)]):
        if dirs_only and (e.is_symlink() or not e.is_dir()):
            continue
        out += [q for q in _files_under(e)
                if _mtime_ns(q) >= since and q.relative_to(root).as_posix() not in before]
    return out


def _mtime_ns(q: Path) -> int:
    try:
        return q.lstat().st_mtime_ns
    except OSError:
        return -1


def _prune_empty(entry: Path) -> None:
    """Remove the folders below ``entry`` (and ``entry``) that are empty."""
    if entry.is_symlink() or not entry.is_dir():
        return
    for root, dirs, _ in os.walk(entry, topdown=False, followlinks=False):
        for d in dirs:
            q = Path(root) / d
            if not q.is_symlink():
                with contextlib.suppress(OSError):
                    q.rmdir()
    with contextlib.suppress(OSError):
        entry.rmdir()


def _shown(paths: list[Path], folder: Path) -> str:
    names = sorted(str(q.relative_to(folder)) for q in paths)
    return ", ".join(names[:5]) + (", ..." if len(names) > 5 else "")


def _check_writable(p: Path, option: str) -> int:
    """Create ``p`` if needed and check that it is a writable folder; the file system's time
    now (ns), read from a probe file.
    """
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
    started_ns = os.fstat(fd).st_mtime_ns  # the file system's own clock
    os.close(fd)
    os.unlink(probe)
    return started_ns


def prepare_output_dir(path: str | os.PathLike, owned: Iterable[str], overwrite: bool = False,
                       option: str = "--out", claim: bool = True, dry_run: bool = False) -> Path:
    """Check (and create) an output folder before a command does any work.

    :param path: the folder
    :param owned: names or glob patterns of the files and folders the command writes there
    :param overwrite: remove the files of earlier runs (those a manifest lists) instead of
        refusing
    :param option: the command-line option that named the folder (for the message)
    :param claim: start the new run's manifest (:data:`MANIFEST`) in the folder
    :param dry_run: check only: remove nothing, claim nothing (the folder is created)
    :return: the folder, created, writable, holding none of the command's files
    :raises OutputDirError: a file in the way, a folder that cannot be created or written,
        earlier results without ``overwrite``, or files of the user's where the command
        writes (never removed)
    """
    p = Path(path)
    started_ns = _check_writable(p, option)
    owned = tuple(owned)
    entries = _owned_entries(p, owned)
    listed = _listed(p, owned)
    ours: list[Path] = []
    theirs: list[Path] = []
    for e in entries:
        loose = _is_pattern_only(e.name, owned) and not e.is_dir()
        for q in _files_under(e):
            if Path(os.path.normpath(q)) in listed:
                ours.append(q)
            elif not loose:  # a user's file where the run writes
                theirs.append(q)
    if theirs:
        raise OutputDirError(f"{option} {p}: holds files that no run's manifest ({MANIFEST}) "
                             f"lists where this command writes ({_shown(theirs, p)}); they are "
                             f"never removed: move them away, or choose another folder")
    if ours and not overwrite:
        names = sorted({q.relative_to(p).parts[0] for q in ours})
        raise OutputDirError(f"output folder {p} already holds results "
                             f"({', '.join(names[:5])}{', ...' if len(names) > 5 else ''}); "
                             f"pass --overwrite to replace them, or choose another folder")
    if dry_run:
        return p
    for q in ours:
        q.unlink()
    for e in entries:
        _prune_empty(e)
    if claim:
        _claim(p, owned, started_ns)
    return p


def _claim(p: Path, owned: tuple[str, ...], started_ns: int) -> None:
    """Start a run's manifest: its owned names, the file system's time, and the files already
    under those names (the user's, left alone: never counted as the run's, whatever their time).
    """
    before = sorted(q.relative_to(p).as_posix() for e in _owned_entries(p, owned)
                    for q in _files_under(e))
    _write_manifest(p, {"format": MANIFEST_FORMAT, "owned": list(owned), "started_ns": started_ns,
                        "preexisting": before, "files": []})


def reopen_output_dir(path: str | os.PathLike, owned: Iterable[str], option: str = "--out") -> Path:
    """Check a folder a command continues a run in (``--resume``): it must be a writable
    folder; its manifest is kept (a folder of an earlier version without one gets one that
    lists what is written from now on).

    :raises OutputDirError: a file in the way, a folder that cannot be created or written
    """
    p = Path(path)
    started_ns = _check_writable(p, option)
    if _read_manifest(p / MANIFEST) is None:
        _claim(p, tuple(owned), started_ns)
    return p


def remove_run_files(path: str | os.PathLike, names: Iterable[str]) -> list[str]:
    """Remove the files of earlier runs (:func:`_listed`) under ``names`` in ``path`` and the
    folders they leave empty; anything else there is left alone.

    :return: the removed files, relative to ``path``
    """
    p = Path(path)
    names = tuple(names)
    listed = _listed(p, names)
    gone = []
    for e in _owned_entries(p, names):
        for q in _files_under(e):
            if Path(os.path.normpath(q)) in listed:
                q.unlink()
                gone.append(q.relative_to(p).as_posix())
        _prune_empty(e)
    return sorted(gone)


def _is_pattern_only(name: str, owned: tuple[str, ...]) -> bool:
    """``name`` matches only glob patterns of ``owned`` (no exact name): a user's file of that
    kind beside the results is left alone, not refused.
    """
    return name not in owned


def _write_manifest(folder: Path, data: dict) -> None:
    atomic_write_text(folder / MANIFEST, json.dumps(data, indent=1) + "\n")


def update_manifest(path: str | os.PathLike) -> list[str]:
    """Bring the run's manifest in ``path`` up to date: the files under its owned names
    written since the folder was claimed (and those listed before, still there).

    :return: the listed files, relative to ``path``, sorted (empty without a manifest)
    """
    p = Path(path)
    data = _read_manifest(p / MANIFEST)
    if data is None:
        return []
    files = {f for f in data.get("files", []) if isinstance(f, str) and (p / f).exists()}
    files.update(q.relative_to(p).as_posix() for q in _written_since_claim(p, data))
    data["files"] = sorted(files)
    _write_manifest(p, data)
    return data["files"]


@contextlib.contextmanager
def manifest_kept(path: str | os.PathLike) -> Iterator[Path]:
    """Context manager: :func:`update_manifest` of ``path`` when the block ends, however it ends
    (an error, Ctrl-C).
    """
    try:
        yield Path(path)
    finally:
        update_manifest(path)


@contextlib.contextmanager
def atomic_folder(path: str | os.PathLike) -> Iterator[Path]:
    """Context manager: write a whole folder atomically.

    The block writes into a temporary sibling folder (yielded); when it ends without an error
    the folder takes ``path``'s place by a rename (an earlier folder there is moved aside and
    removed only after), so ``path`` is either the old folder or the complete new one, never a
    half-written one.  On an error the temporary folder is removed.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        old = None
        if p.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".old", dir=p.parent))
            os.replace(p, old / p.name)
        os.replace(tmp, p)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


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
