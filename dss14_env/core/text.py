"""Small text helpers for the messages and reports.

>>> counted(1, "chunk"), counted(3, "seed")
('1 chunk', '3 seeds')
"""

from __future__ import annotations


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``"<n> <noun>"`` with the noun in the plural unless ``n`` is 1 (default plural: ``noun + "s"``)."""
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"
