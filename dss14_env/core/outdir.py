"""Output folders and result files of the commands: checked before any work, written atomically.

Every command that writes results (``dss14 bench``, ``dss14 train``, ``dss14 reproduce``, the
campaigns) owns a set of names in its output folder (exact names or glob patterns).
:func:`prepare_output_dir` runs before any work: it refuses a path that is a file, a folder
that cannot be created or written, a folder another run is writing into (:mod:`folderlock`),
a folder of another command, and a folder that already holds results of the command unless
``overwrite`` is given.

Every run writes a **manifest**, :data:`MANIFEST` (``dss14_manifest.json``), beside its
results: the command it belongs to and the files it wrote.  Ownership comes from the manifest
alone: a file is a run's when a manifest lists it (or it lies in a folder the manifest lists,
a temporary folder the run made), never from its time or its name.  The writers record every
file in the manifest of the folder the process holds *before* writing it
(:func:`atomic_write_bytes`, :func:`atomic_folder`, :func:`record_files` for a library's
files), so a run killed at any moment leaves only listed files.  ``overwrite`` removes exactly
the listed files (and folders they leave empty) -- never a file no run wrote: a user's files
in the folder survive, wherever they are.  A file of the user's where the run would write (an
owned exact name, or anything inside an owned folder) is refused before anything is removed,
naming it.  One folder belongs to one command: a bench never writes into a campaign's folder.

:func:`atomic_write_text` and :func:`atomic_write_bytes` write a file through a temporary
file in the same folder and an atomic rename, so an interrupted run never leaves a
half-written result file; :func:`atomic_folder` does the same for a whole folder.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp()) / "out"
>>> prepare_output_dir(d, owned=("results.json",), command="bench") == d
True
>>> atomic_write_text(d / "results.json", "{}")
>>> update_manifest(d)
['results.json']
>>> release_output_dir(d)
>>> prepare_output_dir(d, owned=("results.json",), command="bench")
Traceback (most recent call last):
...
dss14_env.core.outdir.OutputDirError: output folder ... already holds results (results.json); ...
>>> prepare_output_dir(d, owned=("results.json",), command="campaign", overwrite=True)
Traceback (most recent call last):
...
dss14_env.core.outdir.OutputDirError: --out ...: holds the results of 'dss14 bench' ...
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path, PurePosixPath
from typing import Any

from dss14_env.core.folderlock import (
    LOCK_FILE,
    folder_free,
    folder_locked,
    held_root,
    lock_folder,
    unlock_folder,
)

#: the manifest file of a run: the files it wrote (``overwrite`` removes those, nothing else)
MANIFEST = "dss14_manifest.json"
#: the manifest's format tag
MANIFEST_FORMAT = "dss14-manifest-1"
#: the largest manifest read, bytes (a run of many checkpoints lists some thousand files)
MAX_MANIFEST_BYTES = 16 * 2**20
#: the manifest's lists of paths (relative to its folder)
_PATH_LISTS = ("owned", "files", "folders")


class OutputDirError(ValueError):
    """An output folder that cannot be used; the message is one line naming the path."""


def _owned_entries(folder: Path, owned: Iterable[str]) -> list[Path]:
    """The top-level entries of ``folder`` that match the owned names (sorted, unique)."""
    found: dict[str, Path] = {}
    for pattern in owned:
        for q in folder.glob(pattern):
            if q.name not in (MANIFEST, LOCK_FILE):
                found[q.name] = q
    return [found[k] for k in sorted(found)]


def _files_under(entry: Path) -> list[Path]:
    """``entry`` itself (a file or link) or every file below it (links not followed; lock
    files left out).
    """
    if entry.is_symlink() or not entry.is_dir():
        return [entry]
    out = []
    for root, dirs, files in os.walk(entry, followlinks=False):
        out += [Path(root) / f for f in files if f != LOCK_FILE]  # a nested run's lock: no result
        out += [Path(root) / d for d in dirs if (Path(root) / d).is_symlink()]
    return out


def _inside(rel: object) -> bool:
    """``rel`` is a non-empty relative path that stays inside its folder."""
    if not isinstance(rel, str) or not rel or "\\" in rel:
        return False
    p = PurePosixPath(rel)
    return not p.is_absolute() and ".." not in p.parts


def _read_manifest(path: Path) -> dict | None:
    """The manifest at ``path``, or None when there is none (or not one of ours: then nothing
    counts as a run's).

    :raises OutputDirError: a manifest larger than :data:`MAX_MANIFEST_BYTES`, or one naming a
        path outside its folder (absolute, or with ``..``), naming the file
    """
    try:
        size = path.stat().st_size
    except OSError:
        return None
    if size > MAX_MANIFEST_BYTES:
        raise OutputDirError(f"{path}: {size} bytes, more than a manifest's {MAX_MANIFEST_BYTES}; "
                             f"not written by this package: move it away")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        return None
    for key in _PATH_LISTS:
        value = data.get(key, [])
        if not isinstance(value, list):
            raise OutputDirError(f"{path}: field '{key}': must be a list of paths")
        bad = [v for v in value if not _inside(v)]
        if bad:
            raise OutputDirError(f"{path}: field '{key}': {bad[0]!r} is not a path inside the "
                                 f"folder (absolute, empty or with '..'); not written by this "
                                 f"package: move it away")
    if not isinstance(data.get("command", ""), str):
        raise OutputDirError(f"{path}: field 'command': must be a string")
    return data


def _manifest_folders(folder: Path, owned: Iterable[str]) -> list[Path]:
    """``folder`` and the folders below its owned entries that hold a manifest (a run's own,
    or a nested run's: a campaign's ``seed_<k>/``); nothing else of the folder is searched.
    """
    roots = [folder] if (folder / MANIFEST).is_file() else []
    for e in _owned_entries(folder, owned):
        if e.is_dir() and not e.is_symlink():
            roots += [Path(root) for root, _, files in os.walk(e, followlinks=False)
                      if MANIFEST in files]
    return roots


class _Listed:
    """What the manifests under a folder list: files, and folders every file below which is
    a run's (paths normalised, relative to the same base as the folder).
    """

    def __init__(self, folder: Path, owned: Iterable[str]) -> None:
        self.files: set[Path] = set()
        self.folders: list[Path] = []
        for root in _manifest_folders(folder, owned):
            data = _read_manifest(root / MANIFEST)
            if data is None:
                continue
            self.files.add(_norm(root / MANIFEST))
            self.files.update(_norm(root / rel) for rel in data.get("files", []))
            self.folders += [_norm(root / rel) for rel in data.get("folders", [])]

    def __contains__(self, q: Path) -> bool:
        n = _norm(q)
        return n in self.files or any(f in n.parents for f in self.folders)


def _norm(q: Path) -> Path:
    return Path(os.path.normpath(q))


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


def check_folder_name(path: str | os.PathLike, option: str = "--out") -> None:
    """Refuse an empty folder name (``--out ''``: not the current folder).

    :raises OutputDirError: naming the option
    """
    if not str(path).strip():
        raise OutputDirError(f"{option} {str(path)!r}: is empty; name a folder (e.g. {option} results)")


def _check_writable(path: str | os.PathLike, option: str, create: bool = True) -> Path:
    """Create the folder ``path`` if needed and check that it is a writable folder (without
    ``create``, a missing folder is checked to be one that can be made, and is not made).
    """
    check_folder_name(path, option)
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputDirError(f"{option} {p}: is a file, not a folder")
    if not create and not p.exists():
        up = next(a for a in p.absolute().parents if a.exists())
        if not up.is_dir() or not os.access(up, os.W_OK | os.X_OK):
            raise OutputDirError(f"{option} {p}: cannot create the folder ({up} is not a writable "
                                 f"folder)")
        return p
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
    return p


def _check_command(p: Path, command: str, option: str) -> None:
    """Refuse a folder whose manifest belongs to another command."""
    data = _read_manifest(p / MANIFEST)
    other = None if data is None else data.get("command")
    if other and other != command:
        raise OutputDirError(f"{option} {p}: holds the results of 'dss14 {other}' ({MANIFEST}); "
                             f"'dss14 {command}' writes only into a folder of its own: choose "
                             f"another folder")


def prepare_output_dir(path: str | os.PathLike, owned: Iterable[str], overwrite: bool = False,
                       option: str = "--out", claim: bool = True, dry_run: bool = False, *,
                       command: str) -> Path:
    """Check (and create) an output folder before a command does any work.

    :param path: the folder
    :param owned: names or glob patterns of the files and folders the command writes there
    :param overwrite: remove the files of earlier runs (those a manifest lists) instead of
        refusing
    :param option: the command-line option that named the folder (for the message)
    :param claim: take the folder (its lock, :mod:`~dss14_env.core.folderlock`, until
        :func:`release_output_dir`) and start the new run's manifest (:data:`MANIFEST`) there
    :param dry_run: check only: remove nothing, claim nothing, create nothing
    :param command: the command the run belongs to (``bench``, ``campaign``, ...): a folder
        whose manifest names another is refused, ``overwrite`` or not
    :return: the folder, created, writable, holding none of the command's files
    :raises OutputDirError: an empty path, a file in the way, a folder that cannot be created
        or written, a folder another run is writing into or of another command, earlier
        results without ``overwrite``, or files of the user's where the command writes (never
        removed)
    """
    p = _check_writable(path, option, create=not dry_run)
    owned = tuple(owned)
    if dry_run and not p.exists():
        return p
    take = claim and not dry_run
    held = folder_locked(p)
    if take:
        lock_folder(p, f"dss14 {command}", option)
    try:
        with contextlib.nullcontext() if take else folder_free(p, f"dss14 {command}", option):
            _check_command(p, command, option)
            ours = _earlier_runs(p, owned, overwrite, option)
    except BaseException:
        if take and not held:
            unlock_folder(p)
        raise
    if dry_run:
        return p
    for q in ours:
        q.unlink()
    for e in _owned_entries(p, owned):
        _prune_empty(e)
    if claim:
        _claim(p, owned, command)
    return p


def _earlier_runs(p: Path, owned: tuple[str, ...], overwrite: bool, option: str) -> list[Path]:
    """The files of earlier runs under ``owned`` in ``p`` (refused without ``overwrite``);
    refuses a user's file where the run writes.
    """
    listed = _Listed(p, owned)
    ours: list[Path] = []
    theirs: list[Path] = []
    for e in _owned_entries(p, owned):
        loose = _is_pattern_only(e.name, owned) and not e.is_dir()
        for q in _files_under(e):
            if q in listed:
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
    return ours


def _claim(p: Path, owned: tuple[str, ...], command: str) -> None:
    """Start a run's manifest: its command and owned names, no files yet."""
    _write_manifest(p, {"format": MANIFEST_FORMAT, "command": command, "owned": list(owned),
                        "files": [], "folders": []})


def reopen_output_dir(path: str | os.PathLike, owned: Iterable[str], option: str = "--out", *,
                      command: str) -> Path:
    """Check and take a folder a command continues a run in (``--resume``): it must be a
    writable folder no other run is writing into, of this command; its manifest is kept (a
    folder of an earlier version without one gets one that lists what is written from now on).

    :raises OutputDirError: a file in the way, a folder that cannot be created or written, in
        use or of another command
    """
    p = _check_writable(path, option)
    held = folder_locked(p)
    lock_folder(p, f"dss14 {command}", option)
    try:
        _check_command(p, command, option)
        data = _read_manifest(p / MANIFEST)
    except BaseException:
        if not held:
            unlock_folder(p)
        raise
    if data is None:
        _claim(p, tuple(owned), command)
    elif not data.get("command"):  # a manifest of an earlier version: now this command's
        data["command"] = command
        _write_manifest(p, data)
    return p


def release_output_dir(path: str | os.PathLike) -> None:
    """The run in ``path`` has ended: drop its lock and those of the runs inside it (nothing
    when this process holds none).
    """
    unlock_folder(path)


def remove_run_files(path: str | os.PathLike, names: Iterable[str]) -> list[str]:
    """Remove the files of earlier runs (those a manifest lists) under ``names`` in ``path``
    and the folders they leave empty; anything else there is left alone.

    :return: the removed files, relative to ``path``
    """
    p = Path(path)
    names = tuple(names)
    listed = _Listed(p, names)
    gone = []
    for e in _owned_entries(p, names):
        for q in _files_under(e):
            if q in listed:
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
    _replace_bytes(folder / MANIFEST, (json.dumps(data, indent=1) + "\n").encode("utf-8"))


def record_files(paths: Iterable[str | os.PathLike], folders: bool = False) -> None:
    """List ``paths`` in the manifest of the run folder this process holds around them, before
    they are written (files a library writes: the atomic writers record their own); paths
    outside every held folder are left alone.

    :param folders: the paths are folders the run has just made: every file below them is
        the run's
    """
    by_root: dict[Path, list[str]] = {}
    for q in paths:
        q = Path(q)
        root = held_root(q)
        if root is not None:
            by_root.setdefault(root, []).append(
                (q.parent.resolve() / q.name).relative_to(root).as_posix())
    for root, rels in by_root.items():
        data = _read_manifest(root / MANIFEST)
        if data is None:
            continue
        key = "folders" if folders else "files"
        inside = [PurePosixPath(f) for f in data.get("folders", [])]
        new = [r for r in rels if not any(f in PurePosixPath(r).parents for f in inside)]
        if set(new) - set(data.get(key, [])):
            data[key] = sorted(set(data.get(key, [])) | set(new))
            _write_manifest(root, data)


def update_manifest(path: str | os.PathLike) -> list[str]:
    """Tidy the run's manifest in ``path``: the files and folders it lists that are gone (a
    temporary file renamed, a run's file removed) are dropped.

    :return: the listed files, relative to ``path``, sorted (empty without a manifest)
    """
    p = Path(path)
    data = _read_manifest(p / MANIFEST)
    if data is None:
        return []
    for key in ("files", "folders"):
        data[key] = sorted({f for f in data.get(key, []) if os.path.lexists(p / f)})
    _write_manifest(p, data)
    return data["files"]


@contextlib.contextmanager
def manifest_kept(path: str | os.PathLike) -> Iterator[Path]:
    """Context manager: the run in ``path``; when the block ends, however it ends (an error,
    Ctrl-C), :func:`update_manifest` and :func:`release_output_dir`.
    """
    try:
        yield Path(path)
    finally:
        try:
            update_manifest(path)
        finally:
            release_output_dir(path)


@contextlib.contextmanager
def atomic_folder(path: str | os.PathLike) -> Iterator[Path]:
    """Context manager: write a whole folder atomically.

    The block writes into a temporary sibling folder (yielded); when it ends without an error
    the folder takes ``path``'s place by a rename (an earlier folder there is moved aside and
    removed only after), so ``path`` is either the old folder or the complete new one, never a
    half-written one.  On an error the temporary folder is removed.  In a held run folder the
    temporary folders and then the new folder's files are listed in its manifest before they
    take their place (:func:`record_files`).
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent))
    try:
        record_files([tmp], folders=True)
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        record_files([p / q.relative_to(tmp) for q in _files_under(tmp)])
        old = None
        if p.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".old", dir=p.parent))
            record_files([old], folders=True)
            os.replace(p, old / p.name)
        os.replace(tmp, p)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and an atomic rename (in a held run
    folder, both listed in its manifest first: :func:`record_files`).
    """
    _replace_bytes(Path(path), data, record=True)


def _replace_bytes(p: Path, data: bytes, record: bool = False) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            if record:
                record_files([Path(tmp), p])
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


def atomic_save_figure(fig: Any, path: str | os.PathLike, dpi: float) -> None:
    """Save a matplotlib figure as a PNG at ``path`` atomically (:func:`atomic_write_bytes`)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    atomic_write_bytes(path, buf.getvalue())
