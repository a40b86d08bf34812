"""Statistics with their uncertainty: bootstrap confidence intervals, interquartile means, ratios.

Everything here resamples *units* that are independent (episodes with their own seeds, training
runs with their own seeds), never samples within one correlated time series, and takes its
randomness from a seeded :class:`numpy.random.Generator`.  The bootstrap is
:func:`scipy.stats.bootstrap` (percentile or BCa intervals).

* :func:`bootstrap_ci`: a statistic of one sample of units and its 95 % interval;
* :func:`ratio_ci`: the ratio of a statistic of two independent samples (e.g. a controller's 3σ
  over the PI's) with a bootstrap interval; ``significant`` is False when the interval contains 1;
* :func:`iqm` and :func:`iqm_ci`: the interquartile mean of per-seed scores of a learned agent
  and its bootstrap interval (the protocol of Agarwal et al., "Deep Reinforcement Learning at
  the Edge of the Statistical Precipice", NeurIPS 2021; one task, so the stratified bootstrap
  is the ordinary one over seeds).

>>> rng = np.random.default_rng(0)
>>> x = rng.normal(10.0, 1.0, 40)
>>> r = bootstrap_ci(x, np.mean, rng=np.random.default_rng(1))
>>> bool(r.low < 10.0 < r.high), r.n
(True, 40)
>>> round(iqm([1.0, 2.0, 3.0, 4.0, 100.0, 5.0, 6.0, 7.0]), 3)
4.5
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

#: default number of bootstrap resamples and confidence level
N_RESAMPLES = 2000
LEVEL = 0.95


@dataclass(frozen=True)
class Estimate:
    """A point estimate with its confidence interval.

    :param value: the statistic on the whole sample
    :param low: lower end of the interval
    :param high: upper end of the interval
    :param n: number of independent units behind it
    :param method: how the interval was computed
    """

    value: float
    low: float
    high: float
    n: int
    method: str

    @property
    def half_width(self) -> float:
        """Half the interval's width."""
        return 0.5 * (self.high - self.low)

    def as_dict(self) -> dict:
        """JSON-ready: ``{"value", "ci95": [low, high], "n", "method"}``."""
        return {"value": self.value, "ci95": [self.low, self.high], "n": self.n,
                "method": self.method}


def _finite(x: Sequence[float] | np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float).ravel()
    if a.size == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: needs a non-empty sample of finite numbers, got {a.size} values")
    return a


def bootstrap_ci(sample: Sequence[float] | np.ndarray, statistic: Callable[[np.ndarray], float],
                 rng: np.random.Generator, n_resamples: int = N_RESAMPLES, level: float = LEVEL,
                 method: str = "percentile") -> Estimate:
    """A statistic of independent units with its bootstrap confidence interval.

    With a single unit the interval is degenerate (``low = high = value``) and ``n`` says so.

    :param sample: one value per independent unit
    :param statistic: function of a 1-d array (e.g. :func:`numpy.mean`, :func:`iqm`)
    :param rng: source of the resampling
    :param n_resamples: bootstrap resamples
    :param level: confidence level
    :param method: ``"percentile"`` or ``"BCa"`` (scipy's names)
    """
    x = _finite(sample, "bootstrap_ci")
    value = float(statistic(x))
    if x.size < 2 or np.all(x == x[0]):
        return Estimate(value, value, value, int(x.size), f"{method} bootstrap (degenerate)")
    res = stats.bootstrap((x,), lambda s, axis=-1: np.apply_along_axis(statistic, axis, s),
                          n_resamples=n_resamples, confidence_level=level, method=method,
                          vectorized=True, random_state=rng)
    lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    return Estimate(value, lo, hi, int(x.size), f"{method} bootstrap over {x.size} units, "
                    f"{n_resamples} resamples")


def iqm(scores: Sequence[float] | np.ndarray) -> float:
    """Interquartile mean: the mean of the middle 50 % (25 % trimmed from each end)."""
    return float(stats.trim_mean(_finite(scores, "iqm"), 0.25))


def iqm_ci(scores: Sequence[float] | np.ndarray, rng: np.random.Generator,
           n_resamples: int = N_RESAMPLES, level: float = LEVEL) -> Estimate:
    """IQM of per-seed scores with its bootstrap (over seeds) confidence interval."""
    return bootstrap_ci(scores, iqm, rng, n_resamples, level)


@dataclass(frozen=True)
class Ratio:
    """A ratio of two statistics with its interval; ``significant``: the interval excludes 1."""

    value: float
    low: float
    high: float
    n_num: int
    n_den: int
    method: str

    @property
    def significant(self) -> bool:
        return not (self.low <= 1.0 <= self.high)

    def as_dict(self) -> dict:
        return {"value": self.value, "ci95": [self.low, self.high], "n": [self.n_num, self.n_den],
                "significant": self.significant, "method": self.method}


def ratio_ci(num: Sequence[float] | np.ndarray, den: Sequence[float] | np.ndarray,
             statistic: Callable[[np.ndarray], float], rng: np.random.Generator,
             n_resamples: int = N_RESAMPLES, level: float = LEVEL, paired: bool = False) -> Ratio:
    """``statistic(num) / statistic(den)`` with a percentile bootstrap interval.

    :param num: units of the numerator (e.g. episodes of one controller)
    :param den: units of the denominator
    :param statistic: function of a 1-d array
    :param paired: the two samples are paired unit by unit (same seeds): resample the pairs
        together (tighter when the units share randomness, e.g. the same gusts); otherwise
        resample each independently
    """
    a, b = _finite(num, "ratio_ci numerator"), _finite(den, "ratio_ci denominator")
    if paired and a.size != b.size:
        raise ValueError(f"ratio_ci: paired samples need equal sizes, got {a.size} and {b.size}")
    value = float(statistic(a) / statistic(b))
    q = ((1 - level) / 2, (1 + level) / 2)
    ra = np.empty(n_resamples)
    for k in range(n_resamples):
        ia = rng.integers(0, a.size, a.size)
        ib = ia if paired else rng.integers(0, b.size, b.size)
        ra[k] = statistic(a[ia]) / statistic(b[ib])
    ra = ra[np.isfinite(ra)]
    lo, hi = (float(v) for v in np.quantile(ra, q)) if ra.size else (math.nan, math.nan)
    how = "paired" if paired else "independent"
    return Ratio(value, lo, hi, int(a.size), int(b.size),
                 f"percentile bootstrap ({how} resampling), {n_resamples} resamples")
