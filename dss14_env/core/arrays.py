"""Reading array files (``.npz``, ``.npy``) written elsewhere: every array's header is measured
before any of its data is read.

A file of a few megabytes can hold a header that claims gigabytes (a zip of zeros compresses
a thousandfold; a ``.npy`` header can claim any shape), and ``numpy.load`` allocates what the
header claims.  :func:`read_arrays` reads the headers first (numpy's own format reader, which
bounds the header's length), refuses object arrays, and refuses a file whose arrays hold more
elements or bytes than the caller's caps, in one line naming the file, before reading data.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import IO

import numpy as np
from numpy.lib import format as npy_format

#: default caps of one array file: elements, bytes (all arrays together) and arrays
MAX_ARRAY_ELEMENTS = 1 << 25
MAX_ARRAY_BYTES = 1 << 28
MAX_ARRAY_MEMBERS = 1024
_ZIP_MAGIC = b"PK"


class ArrayFileError(ValueError):
    """An array file that cannot be read, or that claims more than its caps (one line naming
    the file).
    """


def _header(fh: IO[bytes]) -> tuple[tuple[int, ...], np.dtype]:
    version = npy_format.read_magic(fh)
    if version == (1, 0):
        shape, _, dtype = npy_format.read_array_header_1_0(fh)
    elif version in ((2, 0), (3, 0)):
        shape, _, dtype = npy_format.read_array_header_2_0(fh)
    else:
        raise ValueError(f"unknown .npy format version {version}")
    return tuple(int(n) for n in shape), dtype


def array_headers(path: str | Path) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """``{name: (shape, dtype)}`` of the arrays of an ``.npz`` (or the one array of an ``.npy``,
    named ``""``), read from their headers only.

    :raises ArrayFileError: unreadable, not an array file, more than :data:`MAX_ARRAY_MEMBERS`
    """
    p = Path(path)
    try:
        with p.open("rb") as fh:
            if fh.read(2) != _ZIP_MAGIC:
                fh.seek(0)
                return {"": _header(fh)}
        out = {}
        with zipfile.ZipFile(p) as zf:
            members = zf.infolist()
            if len(members) > MAX_ARRAY_MEMBERS:
                raise ArrayFileError(f"{p}: more than {MAX_ARRAY_MEMBERS} arrays; refused")
            for m in members:
                with zf.open(m) as fh:
                    out[m.filename.removesuffix(".npy")] = _header(fh)
        return out
    except ArrayFileError:
        raise
    except FileNotFoundError:
        raise ArrayFileError(f"{p}: file not found") from None
    except (ValueError, OSError, zipfile.BadZipFile, EOFError, KeyError, SyntaxError) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ArrayFileError(f"{p}: not a readable array file ({first[:160]})") from None


def read_arrays(path: str | Path, max_elements: int = MAX_ARRAY_ELEMENTS,
                max_bytes: int = MAX_ARRAY_BYTES) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` (``{name: array}``; an ``.npy``'s one array is named ``""``),
    read with ``allow_pickle=False`` after :func:`array_headers` showed that they fit the caps.

    :param max_elements: most elements of all arrays together
    :param max_bytes: most bytes of all arrays together
    :raises ArrayFileError: unreadable, an object array, more elements or bytes than the caps
        (one line naming the file and what its headers claim)
    """
    p = Path(path)
    headers = array_headers(p)
    elements = sum(math.prod(shape) for shape, _ in headers.values())
    nbytes = sum(math.prod(shape) * dtype.itemsize for shape, dtype in headers.values())
    if any(dtype.hasobject for _, dtype in headers.values()):
        raise ArrayFileError(f"{p}: holds Python objects (only plain arrays are read); refused")
    if elements > max_elements or nbytes > max_bytes:
        raise ArrayFileError(f"{p}: its headers claim {elements} elements ({nbytes} bytes), more than "
                             f"the {max_elements} elements ({max_bytes} bytes) such a file may hold; "
                             f"refused before reading")
    try:
        with p.open("rb") as fh:
            if fh.read(2) != _ZIP_MAGIC:
                return {"": np.load(p, allow_pickle=False)}
        with np.load(p, allow_pickle=False) as d:
            return {k: d[k] for k in d.files}
    except (ValueError, OSError, zipfile.BadZipFile, EOFError, KeyError) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ArrayFileError(f"{p}: not a readable array file ({first[:160]})") from None


__all__ = ["ArrayFileError", "MAX_ARRAY_BYTES", "MAX_ARRAY_ELEMENTS", "MAX_ARRAY_MEMBERS",
           "array_headers", "read_arrays"]
