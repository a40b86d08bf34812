"""The one result schema: typed records of an episode's figures and of a summary cell, and the
only place that writes them to (and reads them from) the JSON of results.json.

* :class:`ErrorStats`: the statistics of one error signal of one episode (``three_sigma``: 3
  times the standard deviation about the episode's mean, the report's Table 4 quantity;
  ``rms``, mean included; ``max``, largest magnitude; ``mean``) -- :meth:`ErrorStats.of` is
  the one 3σ of the package (the bench, the campaign and the agents' evaluation);
* :class:`EpisodeFigures`: an episode's figures (:data:`ERRORS` per axis, cost, rate command,
  limiter hits, decision times, step response, the command's smoothness);
* :class:`Cell`: a statistic pooled over episodes with its 95 % confidence interval
  (``value``, ``ci95``, ``n_episodes``, ``seconds`` of data behind it, and the spread of
  single episodes: ``median``, ``min``, ``max``);
* :class:`RatioCell`: a ratio with its interval (``significant``: the interval excludes 1;
  None without an interval).

Each has ``to_dict`` (the JSON layout) and ``from_dict``; :func:`summary_cell` and
:func:`ratio_cell` read a summary's cells by quantity, axis and statistic.

>>> ErrorStats.of([1.0, -1.0, 1.0, -1.0]).three_sigma
3.0
>>> Cell.from_dict({"value": 2.0, "ci95": [1.5, 2.5], "n_episodes": 8, "seconds": 80.0}).half_width
0.5
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dss14_env.core.units import AXES

#: pointing-error axes (elevation and cross-elevation)
POINTING_AXES = ("el", "xel")
#: the error quantities of an episode and their axes: the true servo error at the drive
#: encoders (the report's Table 4 quantity) and the dish's true pointing error
ERRORS: Mapping[str, tuple[str, ...]] = {"servo_error_mdeg": AXES, "pointing_error_mdeg": POINTING_AXES}
#: the headline quantity: the dish's true pointing error; the servo error at the drive
#: encoders stays beside it as the report's Table 4 quantity and the calibration anchor
POINTING = "pointing_error_mdeg"
SERVO = "servo_error_mdeg"
#: the pointing axis a drive axis moves the beam on (azimuth: cross-elevation)
POINTING_AXIS_OF: Mapping[str, str] = {"az": "xel", "el": "el"}


def ratio_key(which: str, quantity: str = SERVO) -> str:
    """The key of a summary cell's ratios of ``quantity`` (``vs_reference``, ``vs_yardstick``):
    ``which`` itself for the servo error, ``which_<quantity>`` for the others.

    >>> ratio_key("vs_reference"), ratio_key("vs_reference", POINTING)
    ('vs_reference', 'vs_reference_pointing_error_mdeg')
    """
    return which if quantity == SERVO else f"{which}_{quantity}"


def _float(x: Any) -> float:
    return math.nan if x is None else float(x)


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of one error signal over an episode's scored window (mdeg)."""

    three_sigma: float
    rms: float
    max: float
    mean: float

    @classmethod
    def of(cls, x: Sequence[float] | np.ndarray) -> ErrorStats:
        """The statistics of the samples ``x`` (NaN for none; the 3σ, a spread, NaN for fewer
        than 2: one sample has no spread to measure, not a spread of 0).
        """
        x = np.asarray(x, float)
        if x.size == 0:
            return cls(math.nan, math.nan, math.nan, math.nan)
        spread = float(3.0 * x.std()) if x.size >= 2 else math.nan
        return cls(spread, float(np.sqrt(np.mean(x * x))), float(np.max(np.abs(x))), float(x.mean()))

    def to_dict(self) -> dict[str, float]:
        return {"three_sigma": self.three_sigma, "rms": self.rms, "max": self.max, "mean": self.mean}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ErrorStats:
        return cls(*(_float(d.get(k)) for k in ("three_sigma", "rms", "max", "mean")))


@dataclass(frozen=True)
class EpisodeFigures:
    """The figures of one episode (angles in mdeg, after the scenario's warm-up).

    :param n_steps: control periods run
    :param seconds: seconds scored (after the warm-up)
    :param errors: per quantity of :data:`ERRORS`, per axis, its :class:`ErrorStats`
    :param cost_per_step: mean negated reward over the scored window
    :param rate_command_deg_s: per axis ``rms``, ``peak``, ``peak_accel_deg_s2`` of the
        applied rate command
    :param limits: the limiter's ``rate_deg_s`` and ``accel_deg_s2``
    :param limit_hits: steps the limiter clipped the ``rate`` or its change (``accel``)
    :param controller_time_ms: ``median``, ``p95``, ``max`` wall time of one decision
    :param step: per stepped axis, ``overshoot_pct`` and ``settling_time_s`` (None: no step)
    :param smoothness: ``accel_limit_hits_pct`` and, per axis, ``command_change_hf_pct``
        (:mod:`dss14_env.core.smoothness`; None: not measured)
    """

    n_steps: int
    seconds: float
    errors: Mapping[str, Mapping[str, ErrorStats]]
    cost_per_step: float
    rate_command_deg_s: Mapping[str, Mapping[str, float]]
    limits: Mapping[str, float]
    limit_hits: Mapping[str, int]
    controller_time_ms: Mapping[str, float]
    step: Mapping[str, Mapping[str, float]] | None = None
    smoothness: Mapping[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The episode's entry of results.json (before the runner adds seed, health, wind)."""
        out: dict[str, Any] = {"n_steps": int(self.n_steps), "seconds": float(self.seconds)}
        for q, per_axis in self.errors.items():
            out[q] = {ax: s.to_dict() for ax, s in per_axis.items()}
        out.update({"cost_per_step": float(self.cost_per_step),
                    "rate_command_deg_s": {ax: dict(v) for ax, v in self.rate_command_deg_s.items()},
                    "limits": dict(self.limits), "limit_hits": dict(self.limit_hits),
                    "controller_time_ms": dict(self.controller_time_ms)})
        if self.step is not None:
            out["step"] = {ax: dict(v) for ax, v in self.step.items()}
        if self.smoothness is not None:
            out["smoothness"] = {k: dict(v) if isinstance(v, Mapping) else float(v)
                                 for k, v in self.smoothness.items()}
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> EpisodeFigures:
        errors = {q: {ax: ErrorStats.from_dict(v) for ax, v in d[q].items()} for q in ERRORS if q in d}
        return cls(int(d["n_steps"]), float(d["seconds"]), errors, _float(d.get("cost_per_step")),
                   d.get("rate_command_deg_s", {}), d.get("limits", {}), d.get("limit_hits", {}),
                   d.get("controller_time_ms", {}), d.get("step"), d.get("smoothness"))


def episode_error(episode: Mapping[str, Any], quantity: str, axis: str,
                  stat: str = "three_sigma") -> float:
    """One error statistic of a stored episode (e.g. its elevation pointing 3σ)."""
    return float(getattr(ErrorStats.from_dict(episode[quantity][axis]), stat))


@dataclass(frozen=True)
class Cell:
    """A statistic pooled over episodes, with its confidence interval.

    :param value: the pooled statistic
    :param ci95: the 95 % interval ``(low, high)`` (NaN: none, e.g. one episode)
    :param n_episodes: episodes behind it
    :param seconds: seconds of data behind it (warm-ups left out)
    :param median: the median over single episodes
    :param min: the smallest single episode
    :param max: the largest single episode
    """

    value: float
    ci95: tuple[float, float]
    n_episodes: int
    seconds: float = math.nan
    median: float = math.nan
    min: float = math.nan
    max: float = math.nan

    @property
    def half_width(self) -> float:
        """Half the interval's width (NaN without one)."""
        return 0.5 * (self.ci95[1] - self.ci95[0])

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "ci95": [self.ci95[0], self.ci95[1]], "n_episodes": self.n_episodes,
                "seconds": self.seconds, "median": self.median, "min": self.min, "max": self.max}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Cell:
        lo, hi = (_float(x) for x in d.get("ci95", (None, None)))
        return cls(_float(d["value"]), (lo, hi), int(d.get("n_episodes", 0) or 0),
                   _float(d.get("seconds")), _float(d.get("median")), _float(d.get("min")),
                   _float(d.get("max")))


@dataclass(frozen=True)
class RatioCell:
    """A ratio with its interval; ``significant``: the interval excludes 1 (None: no interval)."""

    value: float
    ci95: tuple[float, float]
    significant: bool | None
    n_episodes: int
    extra: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "ci95": [self.ci95[0], self.ci95[1]], "significant": self.significant,
                "n_episodes": self.n_episodes, **self.extra}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RatioCell:
        lo, hi = (_float(x) for x in d.get("ci95", (None, None)))
        extra = {k: v for k, v in d.items() if k not in ("value", "ci95", "significant", "n_episodes")}
        return cls(_float(d.get("value")), (lo, hi), d.get("significant"), int(d.get("n_episodes", 0) or 0),
                   extra)


def summary_cell(cell: Mapping[str, Any] | None, quantity: str, axis: str,
                 stat: str = "three_sigma") -> Cell | None:
    """The pooled ``stat`` of ``quantity`` on ``axis`` of one summary cell (controller x
    scenario), or None when the cell or the entry is missing.
    """
    try:
        return Cell.from_dict(cell[quantity][axis][stat])  # type: ignore[index]
    except (KeyError, TypeError):
        return None


def ratio_cell(cell: Mapping[str, Any] | None, which: str, axis: str,
               quantity: str = SERVO) -> RatioCell | None:
    """The ratio ``which`` (``vs_reference``, ``vs_yardstick``) of ``quantity``'s 3σ on
    ``axis`` of one summary cell, or None.
    """
    try:
        return RatioCell.from_dict(cell[ratio_key(which, quantity)][axis])  # type: ignore[index]
    except (KeyError, TypeError):
        return None


def jsonable(x: Any) -> Any:
    """``x`` with records, numpy scalars and arrays turned into Python numbers, dicts and lists."""
    if isinstance(x, (ErrorStats, EpisodeFigures, Cell, RatioCell)):
        return jsonable(x.to_dict())
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return [jsonable(v) for v in x.tolist()]
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


__all__ = ["Cell", "ERRORS", "EpisodeFigures", "ErrorStats", "POINTING", "POINTING_AXES",
           "POINTING_AXIS_OF", "RatioCell", "SERVO", "episode_error", "jsonable", "ratio_cell",
           "ratio_key", "summary_cell"]
