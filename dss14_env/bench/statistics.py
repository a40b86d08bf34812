"""Summaries of a controller's episodes in one scenario: every figure pooled over the
episodes with its 95 % confidence interval, and the ratios to the reference controller and to
the yardstick.

**Summary per controller and scenario** (:func:`summarise`): every metric pooled over the
episodes with a 95 % confidence interval, ``{"value", "ci95": [lo, hi], "n_episodes",
"seconds", "median", "min", "max"}`` (``seconds``: the data behind it, warm-ups left out;
``median``, ``min``, ``max``: over the episodes, the spread of single episodes).  Spreads pool
as root mean squares (the pooled 3σ of n equal episodes is ``sqrt(mean(three_sigma_i ** 2))``),
peaks, means, costs, overshoots and the command's smoothness as means, times as medians; the
interval is the percentile bootstrap over episodes (:func:`dss14_env.core.stats.pooled_estimates`),
all metrics of a cell resampled together from a generator seeded by the cell's name
(:func:`cell_rng`), so a rerun
reproduces it.  The command's smoothness (``smoothness``: acceleration-limit hits in % of
the periods, and per axis the share of the command change's variance above 5 Hz in %) is
defined once in :mod:`dss14_env.core.smoothness`, where every episode's figures are computed.
Ratios (``three_sigma`` per axis): ``vs_reference``, over the reference
controller (default the report's PI, ``pi_kp1``) on the seeds both ran, resampling the pairs
together; ``vs_yardstick``, over the yardstick's analytic expected 3σ
(:func:`dss14_env.baselines.yardstick.expected_performance`) for scenarios with one fixed wind,
and ``vs_yardstick_pointing_error_mdeg`` (per pointing axis, el and xel), the pointing error's
over the pointing yardstick's;
each ``{"value", "ci95", "significant", "n_episodes"}``, with ``significant`` False when the
interval contains 1 (None without an interval).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dss14_env.bench.catalog import Scenario
from dss14_env.core import stats
from dss14_env.core.results import ERRORS, POINTING_AXES, SERVO, Cell, RatioCell, episode_error, ratio_key
from dss14_env.core.units import AXES, KMH

#: confidence level of every interval
LEVEL = stats.LEVEL
#: bootstrap resamples per summary cell
N_RESAMPLES = stats.N_RESAMPLES
#: how each per-episode metric is pooled over episodes (:data:`dss14_env.core.stats.POOLINGS`)
ERROR_POOLING = {"three_sigma": "rms", "rms": "rms", "max": "mean", "mean": "mean"}
RATE_POOLING = {"rms": "rms", "peak": "mean", "peak_accel_deg_s2": "mean"}
STEP_POOLING = {"overshoot_pct": "mean", "settling_time_s": "median", "peak_error_mdeg": "mean",
                "settled_rms_mdeg": "rms"}
TIME_POOLING = {"median": "median", "p95": "median", "max": "median"}

# ------------------------------------------------------------------------- summaries
def cell_rng(*names: str, seed: int = 0) -> np.random.Generator:
    """The bootstrap generator of a summary cell: seeded by ``seed`` and the cell's names."""
    return np.random.default_rng([int(seed)] + [zlib.crc32(n.encode()) for n in names])


#: the pooling of every pooled metric by its top-level key: one rule, or one per statistic
POOLING: dict[str, str | dict[str, str]] = {
    "servo_error_mdeg": ERROR_POOLING, "pointing_error_mdeg": ERROR_POOLING, "cost_per_step": "mean",
    "rate_command_deg_s": RATE_POOLING, "limit_hits": "mean", "controller_time_ms": TIME_POOLING,
    "step": STEP_POOLING, "smoothness": "mean"}


def flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested dicts as ``{"a.b.c": leaf}``."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _pooling(path: str) -> str | None:
    rule = POOLING.get(path.split(".", 1)[0])
    if isinstance(rule, dict):
        return rule.get(path.rsplit(".", 1)[-1])
    return rule


def _columns(episodes: Sequence[Mapping[str, Any]]) -> tuple[dict[str, list[float]], dict[str, str]]:
    """Per-episode values of every pooled metric, keyed by their path, and their pooling
    (NaN where an episode lacks the metric, e.g. a step response on an axis without a step).
    """
    flats = [flatten({k: ep[k] for k in POOLING if k in ep}) for ep in episodes]
    paths: list[str] = []
    for f in flats:
        paths += [p for p in f if p not in paths and _pooling(p) is not None]
    cols = {p: [math.nan if f.get(p) is None else float(f[p]) for f in flats] for p in paths}
    return cols, {p: str(_pooling(p)) for p in paths}


def _cell(est: stats.Estimate, values: Sequence[float], seconds: float) -> dict[str, Any]:
    v = np.asarray(values, float)
    v = v[~np.isnan(v)]
    spread = (float(np.median(v)), float(np.min(v)), float(np.max(v))) if v.size else (math.nan,) * 3
    return Cell(est.value, (est.low, est.high), est.n, seconds, *spread).to_dict()


def _nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for path, v in flat.items():
        d = out
        *head, last = path.split(".")
        for h in head:
            d = d.setdefault(h, {})
        d[last] = v
    return out


def summarise(episodes: Sequence[Mapping[str, Any]], rng: np.random.Generator | None = None,
              n_resamples: int = N_RESAMPLES, level: float = LEVEL) -> dict[str, Any]:
    """Every metric of one controller and scenario pooled over its episodes, with its
    confidence interval (see the module docstring).

    :param episodes: :func:`episode_metrics` dicts (with ``seed``)
    :param rng: bootstrap generator, default seeded with 0
    :return: ``n_episodes``, ``seeds``, ``seconds``, the metrics as ``{"value", "ci95",
        "n_episodes", "seconds", "median", "min", "max"}``, ``limit_hits`` (``rate``/``accel`` totals and
        ``per_episode``), ``fallbacks``, ``failures``, ``terminated`` (totals)
    """
    rng = np.random.default_rng(0) if rng is None else rng
    cols, pool = _columns(episodes)
    est = stats.pooled_estimates(cols, pool, rng, n_resamples, level)
    secs = [float(ep.get("seconds", math.nan)) for ep in episodes]
    cells = {}
    for path, e in est.items():
        ok = [s for s, v in zip(secs, cols[path], strict=True) if not math.isnan(v)]
        cells[path] = _cell(e, cols[path], float(np.sum(ok)))
    nested = _nest(cells)
    s: dict[str, Any] = {"n_episodes": len(episodes), "seeds": [int(ep["seed"]) for ep in episodes],
                         "seconds": float(np.nansum(secs))}
    for key in ("servo_error_mdeg", "pointing_error_mdeg", "cost_per_step", "rate_command_deg_s",
                "controller_time_ms"):
        s[key] = nested[key]
    s["limit_hits"] = {k: int(sum(ep["limit_hits"][k] for ep in episodes)) for k in ("rate", "accel")}
    s["limit_hits"]["per_episode"] = nested["limit_hits"]
    s["fallbacks"] = int(sum(ep.get("fallbacks", 0) for ep in episodes))
    s["failures"] = int(sum(ep["failures"] for ep in episodes))
    s["terminated"] = int(sum(ep["terminated"] for ep in episodes))
    for key in ("step", "smoothness"):
        if key in nested:
            s[key] = nested[key]
    return s


def _ratio_dict(r: stats.Ratio) -> dict[str, Any]:
    return RatioCell(r.value, (r.low, r.high), r.significant, r.n_num).to_dict()


def reference_ratios(episodes: Sequence[Mapping[str, Any]], reference: Sequence[Mapping[str, Any]],
                     rng: np.random.Generator, n_resamples: int = N_RESAMPLES,
                     level: float = LEVEL, quantity: str = SERVO) -> dict[str, Any]:
    """Pooled 3σ of ``quantity`` (:data:`dss14_env.core.results.ERRORS`: the servo error at
    the encoders, az / el, or the dish's pointing error, el / xel) of ``episodes`` over the
    reference's, per axis, on the seeds both ran (paired bootstrap).
    """
    axes = ERRORS[quantity]
    ref = {int(ep["seed"]): ep for ep in reference}
    common = [ep for ep in episodes if int(ep["seed"]) in ref]
    num = {ax: [episode_error(ep, quantity, ax) for ep in common] for ax in axes}
    den = {ax: [episode_error(ref[int(ep["seed"])], quantity, ax) for ep in common] for ax in axes}
    r = stats.paired_ratios(num, den, {ax: "rms" for ax in axes}, rng, n_resamples, level)
    return {ax: _ratio_dict(r[ax]) for ax in axes}


def all_reference_ratios(episodes: Sequence[Mapping[str, Any]],
                         reference: Sequence[Mapping[str, Any]], names: Sequence[str],
                         seed: int = 0, n_resamples: int = N_RESAMPLES) -> dict[str, Any]:
    """The ratios to the reference of every error quantity, keyed by
    :func:`dss14_env.core.results.ratio_key` (``vs_reference``: the servo error;
    ``vs_reference_pointing_error_mdeg``: the pointing error), each from its own generator
    (:func:`cell_rng` of ``names``, plus the quantity for all but the servo error).
    """
    out = {}
    for q in ERRORS:
        extra = () if q == SERVO else (q,)
        out[ratio_key("vs_reference", q)] = reference_ratios(
            episodes, reference, cell_rng(*names, *extra, seed=seed), n_resamples, quantity=q)
    return out


def yardstick_ratios(summary: Mapping[str, Any], ref: Mapping[str, Any], pointing: bool = False
                     ) -> dict[str, Any]:
    """Pooled 3σ per axis over a yardstick's analytic (exact) expected 3σ; the interval is
    the controller's, divided by the same number.  Default: the servo error (az, el) over the
    encoder yardstick's; ``pointing``: the pointing error (el, xel) over the pointing
    yardstick's (``ref["pointing"]``).
    """
    metric, key, axes = ("servo_error_mdeg", "three_sigma_mdeg", AXES)
    if pointing:
        metric, key, axes, ref = ("pointing_error_mdeg", "pointing_three_sigma_mdeg", POINTING_AXES,
                                  ref["pointing"])
    out = {}
    for i, ax in enumerate(axes):
        c = summary[metric][ax]["three_sigma"]
        y = float(ref[key][i])
        r = stats.Ratio(c["value"] / y, c["ci95"][0] / y, c["ci95"][1] / y, c["n_episodes"], 1,
                        "the controller's interval over the analytic figure")
        out[ax] = _ratio_dict(r)
    return out


def yardstick_reference(scenario: Scenario, env: Any) -> dict[str, Any] | None:
    """The yardsticks' expected performance for a scenario with one fixed wind, else None: the
    encoder yardstick's, the pointing yardstick's under ``"pointing"``
    (:func:`dss14_env.baselines.yardstick.references`), on the model the environment runs on
    (a drive variant's, with its wind loads, when the environment runs on a model file).
    """
    kw = scenario.env
    speed, direction = kw.get("wind_speed_kmh"), kw.get("wind_direction")
    if not isinstance(speed, (int, float)) or speed <= 0 or direction in (None, "random"):
        return None
    from dss14_env.baselines.yardstick import references
    plants = getattr(getattr(env, "unwrapped", env), "plants", None)
    return references(env, speed * KMH, direction,
                      None if plants is None or plants.source is None else plants)


__all__ = ["ERROR_POOLING", "LEVEL", "N_RESAMPLES", "POOLING", "RATE_POOLING", "STEP_POOLING",
           "TIME_POOLING", "all_reference_ratios", "cell_rng", "flatten", "reference_ratios",
           "summarise", "yardstick_ratios", "yardstick_reference"]
