"""The one grammar of ``--seeds`` in every command: seeds (or seed indices) as values and
ranges, ``0 3 7`` or ``0-4``; a single value is that one seed, never a count (``dss14 bench``
takes a count as ``--episodes N``).

>>> parse_seed_list(["0-2", "7"])
[0, 1, 2, 7]
>>> parse_seed_list(["5"])
[5]
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from dss14_env.core.counts import MAX_SEED_VALUE, MAX_SEEDS


def parse_seed_list(values: Sequence[str | int], option: str = "--seeds",
                    error: type[ValueError] = ValueError) -> list[int]:
    """Seeds from ``--seeds`` values: non-negative integers and ranges ``lo-hi`` (both ends
    included), none repeated, at least one, at most :data:`~dss14_env.core.counts.MAX_SEEDS` in
    all, each at most :data:`~dss14_env.core.counts.MAX_SEED_VALUE` (a range is measured before
    it is built).

    :param values: the option's values (strings from the command line, or ints)
    :param option: the option's name, first in every message
    :param error: the exception class raised (a :class:`ValueError`)
    :raises error: a value that is not a seed or a range, an empty range, a repeated seed, none
    """
    out: list[int] = []
    for v in values:
        s = str(v).strip()
        m = re.fullmatch(r"(\d+)-(\d+)", s)
        if m:
            lo, hi = int(m[1]), int(m[2])
            if hi < lo:
                raise error(f"{option}: empty range {s!r}")
        elif re.fullmatch(r"\d+", s):
            lo = hi = int(s)
        else:
            raise error(f"{option}: expected seed indices (0 3 7) or a range (0-4), got {s!r}")
        if hi > MAX_SEED_VALUE:
            raise error(f"{option}: a seed is at most {MAX_SEED_VALUE}, got {s!r}")
        if len(out) + hi - lo + 1 > MAX_SEEDS:
            raise error(f"{option}: at most {MAX_SEEDS} seeds, got {s!r}"
                        + (f" after {len(out)} others" if out else ""))
        out += list(range(lo, hi + 1))
    if not out:
        raise error(f"{option}: no seed given")
    if len(set(out)) != len(out):
        raise error(f"{option}: a seed is repeated: {out}")
    return out


__all__ = ["parse_seed_list"]
