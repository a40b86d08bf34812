"""The one rule for every count a command takes (episodes, steps, plants, seeds, chunk sizes):
an integer (never a bool) between a lower bound and a finite upper bound, refused in one line
naming the option before any work -- so that a typo (``--episodes 100000000``) is an error, not
gigabytes of memory and a traceback.

>>> check_count(5, "--plants", 1, MAX_PLANTS)
5
>>> check_count(10**9, "--plants", 1, MAX_PLANTS)
Traceback (most recent call last):
...
ValueError: --plants: must be an integer >= 1 and <= 100000, got 1000000000
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: most episodes (seeds) of one scenario or sweep point, and most seed values one option lists
MAX_EPISODES = 100_000
MAX_SEEDS = MAX_EPISODES
#: longest episode, control periods (5.6 h at 0.02 s; one row of the runner's output arrays)
MAX_EPISODE_STEPS = 1_000_000
#: most plants of a campaign (and plants per chunk), and the largest index of its first plant
MAX_PLANTS = 100_000
MAX_FIRST_PLANT = 10**9
#: largest seed value: numpy's int64, which holds every array of seeds
MAX_SEED_VALUE = 2**63 - 1
#: most threads of a thread pool (BLAS, torch) a command or configuration may ask for
MAX_THREADS = 256


def check_count(value: Any, option: str, lo: int, hi: int, error: type[ValueError] = ValueError) -> int:
    """``value`` as an ``int`` in ``[lo, hi]``.

    :param option: the option's name, first in the message
    :param error: the exception class raised (a :class:`ValueError`)
    :raises error: ``<option>: must be an integer >= lo and <= hi, got <value>``
    """
    integer = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    if not integer or not lo <= value <= hi:
        raise error(f"{option}: must be an integer >= {lo} and <= {hi}, got {value!r}")
    return int(value)


__all__ = ["MAX_EPISODES", "MAX_EPISODE_STEPS", "MAX_FIRST_PLANT", "MAX_PLANTS", "MAX_SEEDS",
           "MAX_SEED_VALUE", "MAX_THREADS", "check_count"]
