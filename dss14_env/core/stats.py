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
  is the ordinary one over seeds);
* :func:`pooled_estimates` and :func:`paired_ratios`: many statistics of the same units at
  once, for a benchmark table: each unit (episode) gives one value per metric, every metric is
  pooled over the units (:data:`POOLINGS`: ``mean``, ``rms``, ``median``) and all of them are
  resampled with the *same* bootstrap draws (:func:`bootstrap_counts`), so a ratio of two of
  them, or of two controllers on the same units, keeps its correlation.

The pooled interval is the percentile interval of the bootstrap distribution (Efron &
Tibshirani, *An Introduction to the Bootstrap*, 1993, ch. 13).  ``rms`` pooling is the one for
spreads: the pooled 3σ of n episodes of equal length is ``sqrt(mean(three_sigma_i ** 2))``,
3 x the standard deviation of all their samples about each episode's own mean.

>>> counts = bootstrap_counts(4, np.random.default_rng(0), 3)
>>> counts.shape, counts.sum(axis=1).tolist()
((3, 4), [4.0, 4.0, 4.0])
>>> est = pooled_estimates({"x": [1.0, 2.0, 3.0, 4.0]}, {"x": "rms"}, np.random.default_rng(0))
>>> round(est["x"].value, 4), est["x"].n
(2.7386, 4)

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


#: statistics that reduce along an ``axis`` argument themselves (the others are applied per row)
_AXIS_AWARE = (np.mean, np.median)


def along(statistic: Callable[[np.ndarray], float], x: np.ndarray, axis: int = -1) -> np.ndarray:
    """``statistic`` of every 1-d slice of ``x`` along ``axis``: the vectorised form
    :func:`scipy.stats.bootstrap` calls with a batch of resamples.

    >>> along(np.mean, np.array([[1.0, 3.0], [2.0, 4.0]])).tolist()
    [2.0, 3.0]
    """
    if statistic in _AXIS_AWARE:
        return statistic(x, axis=axis)
    if statistic is iqm:  # the trimmed mean reduces along an axis itself (the same numbers)
        return stats.trim_mean(x, 0.25, axis=axis)
    return np.apply_along_axis(statistic, axis, x)


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
    res = stats.bootstrap((x,), lambda s, axis=-1: along(statistic, s, axis),
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
    def significant(self) -> bool | None:
        """True when the interval excludes 1, False when it contains 1, None without an
        interval (fewer than 2 units).
        """
        if math.isnan(self.low) or math.isnan(self.high):
            return None
        return not (self.low <= 1.0 <= self.high)

    def as_dict(self) -> dict:
        return {"value": self.value, "ci95": [self.low, self.high], "n": [self.n_num, self.n_den],
                "significant": self.significant, "method": self.method}


def ratio_ci(num: Sequence[float] | np.ndarray, den: Sequence[float] | np.ndarray,
             statistic: Callable[[np.ndarray], float], rng: np.random.Generator,
             n_resamples: int = N_RESAMPLES, level: float = LEVEL, paired: bool = False) -> Ratio:
    """``statistic(num) / statistic(den)`` with a percentile bootstrap interval: the
    ``level`` quantiles of :func:`scipy.stats.bootstrap`'s distribution (vectorised, ``paired``
    as below), resamples whose ratio is not finite left out; with fewer than 2 units the
    interval is the value itself.

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
    if min(a.size, b.size) < 2:  # every resample is the sample itself
        lo = hi = value
    else:
        def ratio(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
            return along(statistic, x, axis) / along(statistic, y, axis)

        with np.errstate(divide="ignore", invalid="ignore"):  # a zero denominator: dropped below
            res = stats.bootstrap((a, b), ratio, n_resamples=n_resamples, paired=paired, vectorized=True,
                                  method="percentile", random_state=rng)
        ra = res.bootstrap_distribution
        ra = ra[np.isfinite(ra)]  # a resample whose denominator is 0 has no ratio
        q = ((1 - level) / 2, (1 + level) / 2)
        lo, hi = (float(v) for v in np.quantile(ra, q)) if ra.size else (math.nan, math.nan)
    how = "paired" if paired else "independent"
    return Ratio(value, lo, hi, int(a.size), int(b.size),
                 f"percentile bootstrap ({how} resampling), {n_resamples} resamples")


# ------------------------------------------------------------------ many statistics at once
def _mean(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis)


def _rms(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.sqrt(np.mean(np.square(x), axis=axis))


def _median(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(x, axis=axis)


#: how a metric's per-unit values are pooled into one figure: ``mean``, ``rms`` (root mean
#: square: pooled standard deviations and rms values of equal-length episodes) or ``median``
#: (robust, e.g. for settling times that can be infinite)
POOLINGS: dict[str, Callable[..., np.ndarray]] = {"mean": _mean, "rms": _rms, "median": _median}


def bootstrap_counts(n: int, rng: np.random.Generator, n_resamples: int = N_RESAMPLES) -> np.ndarray:
    """Bootstrap resamples of ``n`` units as counts: row ``b`` says how often each unit was
    drawn (``n`` draws with replacement), shape ``(n_resamples, n)``.

    One counts matrix resamples every metric of the same units together: a mean is
    ``counts @ values / n``.

    :param n: number of units (>= 1)
    :param rng: source of the draws
    :param n_resamples: number of resamples
    """
    if n < 1 or n_resamples < 1:
        raise ValueError(f"bootstrap_counts: need n >= 1 and n_resamples >= 1, got {n}, {n_resamples}")
    idx = rng.integers(0, n, size=(n_resamples, n))
    flat = (idx + n * np.arange(n_resamples)[:, None]).ravel()
    return np.bincount(flat, minlength=n_resamples * n).reshape(n_resamples, n).astype(float)


def _replicates(values: np.ndarray, counts: np.ndarray, pooling: str) -> np.ndarray:
    """The pooled statistic of every resample: ``values`` (n,) or (n, m), counts (B, n) ->
    (B,) or (B, m).
    """
    n = counts.shape[1]
    if pooling == "mean":
        return counts @ values / n
    if pooling == "rms":
        return np.sqrt(counts @ np.square(values) / n)
    if pooling == "median":
        idx = np.repeat(np.tile(np.arange(n), (counts.shape[0], 1)).ravel(),
                        counts.astype(np.int64).ravel()).reshape(counts.shape[0], n)
        return np.median(values[idx], axis=1)
    raise ValueError(f"unknown pooling {pooling!r}; known: {', '.join(POOLINGS)}")


def percentile_interval(replicates: np.ndarray, level: float = LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """The ``level`` percentile interval of bootstrap replicates along axis 0 (the
    ``inverted_cdf`` quantiles, which stay defined when replicates are infinite).
    """
    q = ((1.0 - level) / 2.0, (1.0 + level) / 2.0)
    lo, hi = np.quantile(replicates, q, axis=0, method="inverted_cdf")
    return lo, hi


def pooled_estimates(values: dict[str, Sequence[float] | np.ndarray], pooling: dict[str, str],
                     rng: np.random.Generator, n_resamples: int = N_RESAMPLES,
                     level: float = LEVEL, counts: np.ndarray | None = None) -> dict[str, Estimate]:
    """Several metrics of the same units, each pooled over the units, with percentile bootstrap
    intervals from one set of resamples.

    Units whose value of a metric is NaN (undefined, e.g. a step response on an axis without a
    step) are left out of that metric only (it then gets its own resamples); infinite values
    are kept (use ``median`` pooling for them).  With fewer than 2 units the interval is
    ``(nan, nan)``: one unit says nothing about the spread.

    :param values: metric name -> one value per unit (all of the same length n)
    :param pooling: metric name -> a key of :data:`POOLINGS`
    :param rng: source of the resampling
    :param n_resamples: bootstrap resamples
    :param level: confidence level
    :param counts: resamples to use (:func:`bootstrap_counts`, shape (B, n)); default drawn here
    :return: metric name -> :class:`Estimate` (``n``: units behind it)
    """
    cols = {k: np.asarray(v, float).ravel() for k, v in values.items()}
    bad = sorted({str(pooling.get(k)) for k in cols if pooling.get(k) not in POOLINGS})
    if bad:
        raise ValueError(f"unknown pooling {', '.join(bad)}; known: {', '.join(POOLINGS)}")
    sizes = {v.size for v in cols.values()}
    if len(sizes) > 1:
        raise ValueError(f"pooled_estimates: metrics of different lengths {sorted(sizes)}")
    n = sizes.pop() if sizes else 0
    out: dict[str, Estimate] = {}
    if n == 0:
        return {k: Estimate(math.nan, math.nan, math.nan, 0, "no units") for k in cols}
    if counts is None and n >= 2:
        counts = bootstrap_counts(n, rng, n_resamples)
    n_b = n_resamples if counts is None else counts.shape[0]
    how = f"percentile bootstrap over {{}} units, {n_b} resamples"
    for k, v in cols.items():
        pool = pooling[k]
        f = POOLINGS[pool]
        keep = ~np.isnan(v)
        x = v[keep]
        if x.size == 0:
            out[k] = Estimate(math.nan, math.nan, math.nan, 0, "no units")
            continue
        value = float(f(x))
        if x.size < 2:
            out[k] = Estimate(value, math.nan, math.nan, int(x.size), "no interval (1 unit)")
            continue
        c = counts if keep.all() else bootstrap_counts(x.size, rng, counts.shape[0] if counts is not None
                                                       else n_resamples)
        with np.errstate(invalid="ignore"):
            lo, hi = percentile_interval(_replicates(x, c, pool), level)
        out[k] = Estimate(value, float(lo), float(hi), int(x.size), how.format(x.size))
    return out


def paired_ratios(num: dict[str, Sequence[float] | np.ndarray], den: dict[str, Sequence[float] | np.ndarray],
                  pooling: dict[str, str], rng: np.random.Generator, n_resamples: int = N_RESAMPLES,
                  level: float = LEVEL) -> dict[str, Ratio]:
    """Ratios ``pooled(num[k]) / pooled(den[k])`` of paired units (the same episodes, e.g. two
    controllers on the same seeds), with percentile bootstrap intervals that resample the pairs
    together (one set of resamples for every metric).

    :param num: metric -> values of the numerator's units
    :param den: metric -> values of the denominator's units, unit by unit the same units
    :param pooling: metric -> a key of :data:`POOLINGS`
    :return: metric -> :class:`Ratio` (``significant``: the interval excludes 1)
    """
    out: dict[str, Ratio] = {}
    counts: np.ndarray | None = None
    for k in num:
        a, b = np.asarray(num[k], float).ravel(), np.asarray(den[k], float).ravel()
        if a.size != b.size:
            raise ValueError(f"paired_ratios: {k}: paired samples need equal sizes, got {a.size}, {b.size}")
        keep = ~(np.isnan(a) | np.isnan(b))
        a, b = a[keep], b[keep]
        f = POOLINGS[pooling[k]]
        if a.size == 0:
            out[k] = Ratio(math.nan, math.nan, math.nan, 0, 0, "no units")
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            value = float(f(a) / f(b))
        if a.size < 2:
            out[k] = Ratio(value, math.nan, math.nan, 1, 1, "no interval (1 pair)")
            continue
        if keep.all():
            if counts is None or counts.shape[1] != a.size:
                counts = bootstrap_counts(a.size, rng, n_resamples)
            c = counts
        else:
            c = bootstrap_counts(a.size, rng, n_resamples)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = _replicates(a, c, pooling[k]) / _replicates(b, c, pooling[k])
            lo, hi = percentile_interval(r, level)
        out[k] = Ratio(value, float(lo), float(hi), int(a.size), int(b.size),
                       f"percentile bootstrap over {a.size} pairs, {c.shape[0]} resamples")
    return out
