"""Reading a file the tools wrote (or a user handed them) with a byte cap applied before
anything is read: a file past its cap is refused with one line naming it, never read whole.

>>> import json, tempfile, pathlib
>>> p = pathlib.Path(tempfile.mkdtemp()) / "a.json"
>>> _ = p.write_text(json.dumps({"n": 1}))
>>> read_json(p)
{'n': 1}
>>> read_text(p, max_bytes=4)
Traceback (most recent call last):
...
ValueError: ...a.json: longer than 4 bytes; not a file of this package
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

#: the largest JSON file read back (the default bench's results.json is about 4 MB)
MAX_JSON_BYTES = 64 << 20


def read_text(path: str | os.PathLike, max_bytes: int, what: str = "file of this package") -> str:
    """The UTF-8 text of ``path``, at most ``max_bytes`` bytes read.

    :param what: what the file should be, for the message of one too long

    :raises OSError: the file cannot be opened or read
    :raises ValueError: one line naming the file: longer than ``max_bytes`` or not UTF-8
    """
    with Path(path).open("rb") as fh:
        raw = fh.read(max_bytes + 1)
    if len(raw) > max_bytes:
        raise ValueError(f"{path}: longer than {max_bytes} bytes; not a {what}")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def read_json(path: str | os.PathLike, max_bytes: int = MAX_JSON_BYTES) -> Any:
    """The JSON document of ``path`` (:func:`read_text`'s cap, then :func:`json.loads`).

    :raises OSError: the file cannot be opened or read
    :raises ValueError: too long, not UTF-8 or not JSON (``json.JSONDecodeError`` is a ValueError)
    """
    return json.loads(read_text(path, max_bytes))
