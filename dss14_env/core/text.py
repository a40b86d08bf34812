r"""Small text helpers for the messages and reports, and the generated blocks of the documents
(``<!-- NAME:start -->`` ... ``<!-- NAME:end -->``: :func:`find_blocks`, :func:`fill_blocks`).

>>> counted(1, "chunk"), counted(3, "seed")
('1 chunk', '3 seeds')
>>> fill_blocks("a\n<!-- t:start -->\nold\n<!-- t:end -->\n", {"t": "new\n"})
'a\n<!-- t:start -->\nnew\n<!-- t:end -->\n'
"""

from __future__ import annotations

import re
import sys

#: a generated block: its start marker (and newline), body and end marker
_BLOCK = re.compile(r"(<!-- (?P<name>[\w-]+):start -->\n)(?P<body>.*?)(<!-- (?P=name):end -->)", re.S)


def tolerant_output() -> None:
    r"""Let stdout and stderr write any character their encoding lacks as an escape (``\u03c3``
    for σ under ``PYTHONIOENCODING=ascii``) instead of raising ``UnicodeEncodeError`` -- a
    ``ValueError`` that would turn a finished run into a reported error.
    """
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None:
            reconfigure(errors="backslashreplace")


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``"<n> <noun>"`` with the noun in the plural unless ``n`` is 1 (default plural: ``noun + "s"``)."""
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"


def find_blocks(text: str) -> dict[str, str]:
    """The generated blocks of a document: ``{name: body}``."""
    return {m["name"]: m["body"] for m in _BLOCK.finditer(text)}


def fill_blocks(text: str, blocks: dict[str, str]) -> str:
    """``text`` with every marked block whose name is in ``blocks`` replaced by its rendering."""
    return _BLOCK.sub(lambda m: m.group(1) + blocks.get(m["name"], m["body"]) + m.group(4), text)
