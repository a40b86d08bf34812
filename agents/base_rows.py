"""A policy interface's batched LQG base when its rows act on environments whose encoders sit in
different places (a training mixture of drive- and axis-encoder holds, or a policy trained on
drive encoders scored on an axis-encoder hold).

The LQG's Kalman filter and integrator are designed for where the encoders sit
(:mod:`dss14_env.baselines.lqg`: an axis-encoder design measures the structure's angles), so a
row's base must be designed for its own environment's ``encoders``: :func:`batched_base` builds
one batched controller per encoder placement present, each over its rows.

The scheduled pointing LQG (``lqg_pointing_sched``,
:class:`dss14_env.baselines.scheduled.ScheduledPointingLQGController`) designs each row's episode
for its mean wind speed reading: :meth:`RowGroupedLQG.set_row_readings` passes the rows'
readings to their groups.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from dss14_env.baselines.lqg import LQGController, PointingLQGController
from dss14_env.baselines.scheduled import ScheduledPointingLQGController


def batched_lqg(env_config: Any, pointing: Any, n: int, scheduled: bool = False) -> LQGController:
    """One batched LQG (``pointing`` None) or pointing-aware LQG of ``n`` rows for ``env_config``;
    with ``scheduled`` the pointing-aware LQG scheduled on each row's mean wind speed reading.
    """
    if scheduled:
        c: LQGController = ScheduledPointingLQGController(env_config, pointing=pointing)
    elif pointing is None:
        c = LQGController(env_config)
    else:
        c = PointingLQGController(env_config, pointing=pointing)
    c.reset_batch(n)
    return c


class RowGroupedLQG:
    """Batched LQG controllers over disjoint groups of rows, seen as one batched controller of
    all rows (the calls :class:`dss14_env.agents.interface.PolicyInterface` makes of its base).

    :param groups: ``(rows, controller)`` pairs: the row indices (together ``0..n-1``, each
        once) and a controller reset to ``len(rows)`` rows
    """

    def __init__(self, groups: Sequence[tuple[np.ndarray, LQGController]]) -> None:
        self.groups = [(np.asarray(rows, int), c) for rows, c in groups]
        self.n = sum(len(rows) for rows, _ in self.groups)
        self._where = np.zeros((self.n, 2), int)  # row -> (group, row within the group)
        for g, (rows, _) in enumerate(self.groups):
            self._where[rows] = np.stack([np.full(len(rows), g), np.arange(len(rows))], 1)

    def act_batch(self, observations: np.ndarray) -> np.ndarray:
        """Every row's command ``(n, 2)`` for observations ``(n, 12)``."""
        out = np.zeros((self.n, 2))
        for rows, c in self.groups:
            out[rows] = c.act_batch(observations[rows])
        return out

    def restart(self, mask: np.ndarray) -> None:
        """Rows ``mask`` (bool ``(n,)``) start new episodes."""
        for rows, c in self.groups:
            c.restart(np.asarray(mask, bool)[rows])

    def disturbance(self, row: int = 0) -> np.ndarray:
        """Row ``row``'s input-disturbance estimate (its group's controller's)."""
        g, i = self._where[row]
        return self.groups[g][1].disturbance(int(i))

    def set_row_readings(self, rows: Sequence[int], wind_speeds: Sequence[float]) -> None:
        """The mean wind speed readings (m/s) of rows ``rows``' next episodes, each passed to its
        group's scheduled controller.
        """
        rows = np.asarray(rows, int).reshape(-1)
        speeds = np.asarray(wind_speeds, float).reshape(-1)
        for g, (_, c) in enumerate(self.groups):
            mine = self._where[rows, 0] == g
            if mine.any():
                c.set_row_readings(self._where[rows[mine], 1], speeds[mine])


def batched_base(env_config: Any, pointing: Any, encoders: Sequence[str],
                 scheduled: bool = False) -> LQGController | RowGroupedLQG:
    """The batched base of rows whose environments have ``encoders`` (one entry per row): one
    controller designed for ``env_config`` when every row's encoders are its own, else one per
    placement, each designed for ``env_config`` with that placement (``scheduled``: as
    :func:`batched_lqg`).
    """
    places = list(dict.fromkeys(encoders))
    if places == [env_config.encoders]:
        return batched_lqg(env_config, pointing, len(encoders), scheduled)
    enc = np.asarray(encoders)
    groups = []
    for place in places:
        rows = np.flatnonzero(enc == place)
        design = dataclasses.replace(env_config, encoders=place)
        groups.append((rows, batched_lqg(design, pointing, len(rows), scheduled)))
    return RowGroupedLQG(groups)


__all__ = ["RowGroupedLQG", "batched_base", "batched_lqg"]
