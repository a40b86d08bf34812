"""The pointing LQG scheduled on the measured mean wind speed (``lqg_pointing_sched``).

``lqg_pointing`` carries one gust model, the design wind's (50 km/h): in light wind its
Kalman filter expects gusts 25 times larger (in torque) than there are and follows the encoders'
quantisation error.  This controller reads the episode's mean wind speed as an anemometer
measures it (:meth:`ScheduledPointingLQGController.set_scenario`; the bench's episode loop
passes the environment's reset-info ``wind_speed_mps``, the mean wind, never the gust state),
rounds it to the nearest speed of the grid of section ``schedule`` of
``configs/controllers.yaml`` and uses that grid point's design: ``lqg_pointing``'s with the
gust model at the point's speed and the point's ``measurement_noise`` (the extra white noise
of the Kalman design: the lighter the wind, the longer the encoders sit on one count and the
less their quantisation error is white).  Everything else is ``lqg_pointing``'s:
the direction read from the start command, the direction-free model below
``lqg.min_wind_speed`` of the inferred speed, the reduction, weights, shaper and integrator.
At the 50-km/h grid point it is ``lqg_pointing``.  Designs are built once per process and
wind (cached as every LQG design is).  The schedule's figures and its light-wind bound:
``docs/results/light_wind.md``.

Without a reading (a loop that does not call :meth:`~ScheduledPointingLQGController.set_scenario`)
an episode takes the speed inferred from its start command
(:func:`dss14_env.baselines.design.infer_wind`, off by the start gust, about 17 % at 1 sigma).

>>> ctrl = ScheduledPointingLQGController()
>>> [round(s * 3.6) for s in ctrl.grid_speeds]
[10, 20, 30, 50, 70]
>>> ctrl.grid_point(12 / 3.6), ctrl.grid_point(44 / 3.6)  # 12 km/h: the 10-km/h point
(0, 3)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from dss14_env.baselines.design import (
    LQGConfig,
    PointingConfig,
    ScheduleConfig,
    default_controllers_config,
    infer_wind,
)
from dss14_env.baselines.lqg import LQGDesign, PointingLQGController, lqg_design_from_config
from dss14_env.core.units import KMH
from dss14_env.envs.config import WIND_SPEED_MAX_KMH

#: the largest mean wind speed reading accepted, m/s (the environment's bound)
MAX_READING = WIND_SPEED_MAX_KMH * KMH


def check_readings(wind_speeds: Any, n: int) -> np.ndarray:
    """``n`` mean wind speed readings as float ``(n,)``, m/s.

    :raises ValueError: one line naming the readings unless there are ``n`` finite speeds in
        ``[0, MAX_READING]``
    """
    try:
        v = np.asarray(wind_speeds, float).reshape(-1)
    except (TypeError, ValueError):
        v = np.array([math.nan])
    if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v < 0) or np.any(v > MAX_READING):
        raise ValueError(f"wind speed reading: {n} finite speeds in 0..{MAX_READING:.4g} m/s "
                         f"({WIND_SPEED_MAX_KMH:g} km/h), one per row, got {wind_speeds!r}")
    return v


class ScheduledPointingLQGController(PointingLQGController):
    """``lqg_pointing`` with its gust model and measurement noise scheduled on the measured mean
    wind speed (see the module docstring).

    ``info["design_wind"]``: ``(grid speed, direction)``, the direction None for the
    direction-free model; ``info_batch``: ``design_wind_speed_mps``,
    ``design_wind_direction_rad`` (NaN: direction-free) and ``wind_reading_mps`` (NaN: no
    reading, the inferred speed was used).

    :param env: the environment (or its config / a :class:`ControlInterface`)
    :param name: label, default ``"LQG-pointing-sched"``
    :param config: the shared LQG settings, default section ``lqg``
    :param pointing: the pointing settings, default section ``pointing``
    :param schedule: the grid, default section ``schedule`` of ``configs/controllers.yaml``
    """

    def __init__(self, env: Any = None, name: str = "LQG-pointing-sched", config: LQGConfig | None = None,
                 pointing: PointingConfig | None = None, schedule: ScheduleConfig | None = None) -> None:
        sc = schedule or default_controllers_config().schedule
        if sc is None:
            raise ValueError("lqg_pointing_sched needs the section 'schedule' of the controllers' "
                             "configuration")
        self.grid_speeds = tuple(float(s) for s in sc.wind_speeds)
        self.measurement_noise = tuple(float(s) for s in sc.measurement_noise)
        self._reading: float | None = None
        super().__init__(env, name, config, pointing)

    def grid_point(self, wind_speed: float) -> int:
        """The index of the grid speed nearest to a mean wind speed (m/s)."""
        return int(np.argmin(np.abs(np.asarray(self.grid_speeds) - float(wind_speed))))

    def design_for(self, wind: Any) -> LQGDesign:
        """The design for a key ``(wind, grid point)`` (cached; :meth:`LQGController.design_for`
        for a plain wind key): ``wind`` ``("design", speed)`` or ``(speed, direction)``, the
        Kalman design with the grid point's measurement noise.
        """
        if not (isinstance(wind, tuple) and len(wind) == 2 and isinstance(wind[1], int)):
            return super().design_for(wind)
        if wind not in self._designs_by_wind:
            cfg = dataclasses.replace(self.config, measurement_noise=self.measurement_noise[wind[1]])
            self._designs_by_wind[wind] = lqg_design_from_config(self.interface, cfg, wind=wind[0],
                                                                 pointing=self.pointing)
        return self._designs_by_wind[wind]

    def _allocate(self, n: int) -> None:
        super()._allocate(n)
        self._row_readings = np.full(n, math.nan)
        self._used_readings = np.full(n, math.nan)
        self._design_keys: list[tuple[float, float | None]] = [(math.nan, None)] * n

    def set_scenario(self, wind_speed: float, direction: Any = None) -> None:
        """The mean wind speed reading (m/s) for the following episodes of :meth:`act` (it holds
        until the next call).  ``direction`` is not used: the direction is read from the start
        command, as ``lqg_pointing`` does.

        :raises ValueError: one line, for a speed that is not finite or outside 0..90 km/h
        """
        self._reading = float(check_readings(wind_speed, 1)[0])

    def set_scenario_batch(self, wind_speeds: Sequence[float], directions: Any = None) -> None:
        """The rows' mean wind speed readings (m/s): row ``i``'s next episode (its first
        :meth:`act_batch` after :meth:`reset_batch` or :meth:`restart`) uses ``wind_speeds[i]``;
        ``directions`` are not used (see :meth:`set_scenario`).

        :raises ValueError: one line, unless there is one finite speed in 0..90 km/h per row
        """
        self._row_readings = check_readings(wind_speeds, self.n)

    def set_row_readings(self, rows: Sequence[int], wind_speeds: Sequence[float]) -> None:
        """The mean wind speed readings (m/s) of the next episodes of rows ``rows`` only (each
        row's first :meth:`act_batch` after :meth:`reset_batch` or :meth:`restart`); the other
        rows keep theirs.

        :raises ValueError: one line, for a row outside ``0..n-1`` or a reading that is not a
            finite speed in 0..90 km/h
        """
        idx = np.asarray(rows, int).reshape(-1)
        if idx.size and (idx.min() < 0 or idx.max() >= self.n):
            raise ValueError(f"wind speed reading: rows must lie in 0..{self.n - 1}, got {idx.tolist()}")
        self._row_readings[idx] = check_readings(wind_speeds, idx.size)

    def restart(self, mask: np.ndarray) -> None:
        """The rows ``mask`` start a new episode at the next :meth:`act_batch` and forget their
        reading (it was the ended episode's): give the new one with :meth:`set_row_readings`,
        else the episode takes the speed of :meth:`set_scenario` or the inferred one.
        """
        super().restart(mask)
        self._row_readings[np.asarray(mask, bool)] = math.nan

    def select_designs(self, rows: np.ndarray, r0: np.ndarray, c_rate0: np.ndarray) -> list[LQGDesign]:
        out = []
        for i, r, v in zip(rows.tolist(), r0, c_rate0, strict=True):
            reading = self._row_readings[i] if math.isfinite(self._row_readings[i]) else self._reading
            self._used_readings[i] = math.nan if reading is None else reading
            j = self.grid_point(infer_wind(r, v)[0] if reading is None else reading)
            speed = self.grid_speeds[j]
            base = self.wind_key(r, v)  # lqg_pointing's: None (direction-free) or (speed, direction)
            wind = ("design", speed) if base is None else (speed, base[1])
            self._design_keys[i] = (speed, None if base is None else base[1])
            self._wind_keys[i] = None
            out.append(self.design_for((wind, j)))
        return out

    def row_info(self) -> dict[str, np.ndarray]:
        w = np.array([(s, math.nan if d is None else d) for s, d in self._design_keys], float)
        return {"design_wind_speed_mps": w[:, 0], "design_wind_direction_rad": w[:, 1],
                "wind_reading_mps": self._used_readings.copy()}

    def episode_info(self) -> dict[str, Any]:
        return {"design_wind": self._design_keys[0]}


__all__ = ["MAX_READING", "ScheduledPointingLQGController", "check_readings"]
