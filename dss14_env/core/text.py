r"""Small text helpers for the messages and reports, and the generated blocks of the documents
(``<!-- NAME:start -->`` ... ``<!-- NAME:end -->``: :func:`find_blocks`, :func:`fill_blocks`,
and :func:`render_block`, the end of every script that renders its results into a document).

>>> counted(1, "chunk"), counted(3, "seed")
('1 chunk', '3 seeds')
>>> fill_blocks("a\n<!-- t:start -->\nold\n<!-- t:end -->\n", {"t": "new\n"})
'a\n<!-- t:start -->\nnew\n<!-- t:end -->\n'
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

#: a generated block: its start marker (and newline), body and end marker
_BLOCK = re.compile(r"(<!-- (?P<name>[\w-]+):start -->\n)(?P<body>.*?)(<!-- (?P=name):end -->)", re.S)


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``"<n> <noun>"`` with the noun in the plural unless ``n`` is 1 (default plural: ``noun + "s"``)."""
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"


def find_blocks(text: str) -> dict[str, str]:
    """The generated blocks of a document: ``{name: body}``."""
    return {m["name"]: m["body"] for m in _BLOCK.finditer(text)}


def fill_blocks(text: str, blocks: dict[str, str]) -> str:
    """``text`` with every marked block whose name is in ``blocks`` replaced by its rendering."""
    return _BLOCK.sub(lambda m: m.group(1) + blocks.get(m["name"], m["body"]) + m.group(4), text)


def add_block_options(parser: argparse.ArgumentParser, doc: str,
                      compute: tuple[str, str] | None = None) -> None:
    """The options of a script that renders its results into a document's block: ``--render``
    (the committed results) and ``--check`` (exit 1 if the document is not their rendering),
    one of them or ``compute`` (``(option, help)``, an option taking a file) required when given.
    """
    group = parser.add_mutually_exclusive_group(required=compute is not None)
    if compute is not None:
        group.add_argument(compute[0], help=compute[1])
    group.add_argument("--render", action="store_true", help=f"render the committed results into {doc}")
    group.add_argument("--check", action="store_true", help=f"exit 1 if {doc} is not their rendering")


def render_block(doc: Path, block: str, body: str, source: Path, command: str, check: bool = False) -> int:
    """Write ``body`` (the rendering of ``source``) into the block ``block`` of the document
    ``doc``, or with ``check`` only compare.

    :param command: the command that renders the block (named when the check fails)
    :return: 0 when written or equal; 1 when the check fails (a line on stdout naming
        ``command``) or ``doc`` has no such block (a line on stderr)
    """
    text = doc.read_text(encoding="utf-8")
    if block not in find_blocks(text):
        print(f"{doc}: no <!-- {block}:start --> ... <!-- {block}:end --> block", file=sys.stderr)
        return 1
    new = fill_blocks(text, {block: body})
    if check:
        if new != text:
            print(f"{doc}: block {block} is not the rendering of {source}; run {command}")
            return 1
        return 0
    doc.write_text(new, encoding="utf-8")
    return 0
