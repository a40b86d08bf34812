"""Tests of the Davenport gust model in :mod:`dss14_env.wind.gusts`."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scipy import optimize, signal

from dss14_env.wind import gusts as wind

KMH = 1.0 / 3.6  # m/s per km/h
U_50 = 50.0 * KMH  # 13.889 m/s
SPEEDS = (30.0 * KMH, 50.0 * KMH, 70.0 * KMH)  # 8.33, 13.89, 19.44 m/s
BAND = (0.003, 10.0)  # Hz


def _log_binned(f: np.ndarray, values: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
    """Split ``values`` into the frequency bins ``edges[i] <= f < edges[i + 1]``."""
    return [values[(f >= lo) & (f < hi)] for lo, hi in zip(edges[:-1], edges[1:], strict=True)]


# --------------------------------------------------------------------------
# generator
# --------------------------------------------------------------------------
@pytest.mark.parametrize("mean_speed", SPEEDS)
def test_record_variance_matches_band_integral_and_6_kappa_u2(mean_speed: float) -> None:
    # 4 independent 48-h records at 0.05 s: the sample variance of one record
    # scatters by ~0.8 % (13.9 m/s); pooled, ~0.4 %.  A 2-h record scatters by ~4 %.
    dt, duration, seeds = 0.05, 48 * 3600.0, (11, 12, 13, 14)
    n = round(duration / dt)
    pooled = np.mean([np.var(wind.generate_gusts(mean_speed, duration, dt, np.random.default_rng(s)))
                      for s in seeds])
    band = wind.davenport_band_variance(mean_speed, 1.0 / (n * dt), 0.5 / dt)
    total = 6.0 * wind.DAVENPORT_KAPPA * mean_speed**2
    assert pooled / band == pytest.approx(1.0, abs=0.03)
    assert pooled / total == pytest.approx(1.0, abs=0.03)  # ~1 % of the variance lies above 10 Hz


@pytest.mark.parametrize("mean_speed", SPEEDS)
def test_welch_psd_within_20_percent_in_log_bins(mean_speed: float) -> None:
    # 2**22 samples at 0.05 s (58 h); 65536-sample segments (3277 s, 0.31 mHz
    # resolution) give >= 5 Welch frequencies in the lowest bin and ~127 averaged segments.
    dt = 0.05
    gusts = wind.generate_gusts(mean_speed, 2**22 * dt, dt, np.random.default_rng(2024))
    f, p = signal.welch(gusts, fs=1.0 / dt, nperseg=2**16)
    f, p = f[1:], p[1:]  # drop DC
    edges = np.geomspace(*BAND, 21)
    edges[-1] *= 1.0 + 1e-12  # include the 10 Hz (Nyquist) bin
    est = _log_binned(f, p, edges)
    ref = _log_binned(f, wind.davenport_psd(f, mean_speed), edges)
    assert min(b.size for b in est) >= 5
    errors = np.array([e.mean() / r.mean() - 1.0 for e, r in zip(est, ref, strict=True)])
    assert np.max(np.abs(errors)) < 0.20, errors


def test_same_seed_gives_identical_series() -> None:
    a = wind.generate_gusts(U_50, 600.0, 0.1, np.random.default_rng(7))
    b = wind.generate_gusts(U_50, 600.0, 0.1, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)


def test_different_seed_gives_different_series() -> None:
    a = wind.generate_gusts(U_50, 600.0, 0.1, np.random.default_rng(7))
    b = wind.generate_gusts(U_50, 600.0, 0.1, np.random.default_rng(8))
    assert not np.allclose(a, b)


@pytest.mark.parametrize("duration, dt, n_expected", [(600.0, 0.1, 6000), (10.0, 0.3, 33), (1.0, 0.5, 2)])
def test_record_length_and_zero_mean(duration: float, dt: float, n_expected: int) -> None:
    gusts = wind.generate_gusts(U_50, duration, dt, np.random.default_rng(0))
    assert gusts.shape == (n_expected,)
    assert abs(gusts.mean()) < 1e-12


def test_generator_leaves_global_rng_alone() -> None:
    np.random.seed(123)
    expected = np.random.random()
    np.random.seed(123)
    wind.generate_gusts(U_50, 600.0, 0.1, np.random.default_rng(1))
    assert np.random.random() == expected


# --------------------------------------------------------------------------
# shaping filter
# --------------------------------------------------------------------------
@pytest.mark.parametrize("mean_speed", SPEEDS)
def test_filter_psd_within_20_percent_of_formula(mean_speed: float) -> None:
    f = np.geomspace(*BAND, 4000)
    ss = wind.davenport_filter(mean_speed)
    ratio = wind.filter_psd(ss, f) / wind.davenport_psd(f, mean_speed)
    assert np.max(np.abs(ratio - 1.0)) < 0.20
    assert wind.davenport_filter_fit_error(mean_speed) == pytest.approx(np.max(np.abs(ratio - 1.0)), abs=2e-3)


@pytest.mark.parametrize("mean_speed", SPEEDS)
def test_filter_is_stable_and_strictly_proper(mean_speed: float) -> None:
    ss = wind.davenport_filter(mean_speed)
    assert np.all(np.linalg.eigvals(ss.A).real < 0.0)
    assert np.all(ss.D == 0.0)
    fit = wind.davenport_normalised_fit()
    assert len(fit.zeros) == len(fit.poles) - 1
    assert min(fit.zeros) > 0.0  # minimum phase: real zeros in the open left half-plane


@pytest.mark.parametrize("mean_speed", SPEEDS)
def test_filter_variance_within_10_percent_of_6_kappa_u2(mean_speed: float) -> None:
    ss = wind.davenport_filter(mean_speed)
    assert wind.filter_variance(ss) / wind.davenport_variance(mean_speed) == pytest.approx(1.0, abs=0.10)


def test_filter_variance_equals_integral_of_one_sided_psd() -> None:
    # checks the convention S_one_sided = 2 |H|^2 for unit two-sided white noise
    ss = wind.davenport_filter(U_50)
    f = np.geomspace(1e-7, 1e5, 200001)
    integral = np.trapezoid(wind.filter_psd(ss, f), f)
    assert integral == pytest.approx(wind.filter_variance(ss), rel=1e-3)


def test_filter_time_scaling_shifts_poles_with_speed() -> None:
    a = np.sort(np.linalg.eigvals(wind.davenport_filter(10.0).A).real)
    b = np.sort(np.linalg.eigvals(wind.davenport_filter(20.0).A).real)
    np.testing.assert_allclose(b, 2.0 * a, rtol=1e-12)


def test_fit_is_deterministic_and_fast() -> None:
    start = time.perf_counter()
    fresh = wind.davenport_normalised_fit.__wrapped__(wind.DEFAULT_FILTER_ORDER)
    elapsed = time.perf_counter() - start
    assert elapsed < 0.5
    assert fresh == wind.davenport_normalised_fit()


@pytest.mark.parametrize("order, max_error", [(4, 0.20), (5, 0.05)])
def test_fit_error_by_order(order: int, max_error: float) -> None:
    assert wind.davenport_filter_fit_error(U_50, order) < max_error


# --------------------------------------------------------------------------
# input validation
# --------------------------------------------------------------------------
_RNG = np.random.default_rng(0)
BAD_CALLS: list[tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any], str]] = [
    (wind.davenport_psd, (0.0, U_50), {}, "f_hz"),
    (wind.davenport_psd, ([0.1, -1.0], U_50), {}, "f_hz"),
    (wind.davenport_psd, (np.inf, U_50), {}, "f_hz"),
    (wind.davenport_psd, (0.1, 0.0), {}, "mean_speed"),
    (wind.davenport_psd, (0.1, np.nan), {}, "mean_speed"),
    (wind.davenport_psd, (0.1, U_50), {"kappa": -0.005}, "kappa"),
    (wind.davenport_psd, (0.1, U_50), {"length": 0.0}, "length"),
    (wind.davenport_variance, (-1.0,), {}, "mean_speed"),
    (wind.davenport_variance, (U_50,), {"kappa": np.inf}, "kappa"),
    (wind.generate_gusts, (0.0, 60.0, 0.1, _RNG), {}, "mean_speed"),
    (wind.generate_gusts, (U_50, -60.0, 0.1, _RNG), {}, "duration"),
    (wind.generate_gusts, (U_50, 60.0, 0.0, _RNG), {}, "dt"),
    (wind.generate_gusts, (U_50, 60.0, np.nan, _RNG), {}, "dt"),
    (wind.generate_gusts, (U_50, 0.1, 1.0, _RNG), {}, "duration"),
    (wind.generate_gusts, (U_50, 60.0, 0.1, 42), {}, "rng"),
    (wind.generate_gusts, (U_50, 60.0, 0.1, np.random.RandomState(0)), {}, "rng"),
    (wind.davenport_filter, (0.0,), {}, "mean_speed"),
    (wind.davenport_filter, (U_50,), {"order": 0}, "order"),
    (wind.davenport_filter, (U_50,), {"order": 2.5}, "order"),
    (wind.davenport_filter, (U_50,), {"kappa": 0.0}, "kappa"),
    (wind.davenport_filter_fit_error, (U_50,), {"f_low": 1.0, "f_high": 0.5}, "f_high"),
    (wind.davenport_band_variance, (U_50, 1.0, 0.5), {}, "f_high"),
]


@pytest.mark.parametrize("func, args, kwargs, name", BAD_CALLS)
def test_bad_inputs_raise_value_error_naming_argument(
    func: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any], name: str
) -> None:
    with pytest.raises(ValueError, match=name):
        func(*args, **kwargs)


def test_unstable_or_proper_system_has_no_finite_variance() -> None:
    with pytest.raises(ValueError, match="stable"):
        wind.filter_variance(signal.StateSpace([[1.0]], [[1.0]], [[1.0]], [[0.0]]))
    with pytest.raises(ValueError, match="D = 0"):
        wind.filter_variance(signal.StateSpace([[-1.0]], [[1.0]], [[1.0]], [[1.0]]))


# --------------------------------------------------------------------------
# units and closed forms
# --------------------------------------------------------------------------
def test_units_sigma_at_50_kmh() -> None:
    u = 50.0 / 3.6
    assert u == pytest.approx(13.889, abs=1e-3)
    sigma = math.sqrt(wind.davenport_variance(u))
    assert sigma == pytest.approx(math.sqrt(6 * 0.005) * u, rel=1e-12)
    assert sigma == pytest.approx(2.41, abs=0.01)


def test_peak_of_f_times_psd_is_at_x_sqrt3() -> None:
    u = 50.0 / 3.6
    res = optimize.minimize_scalar(lambda lf: -math.exp(lf) * float(wind.davenport_psd(math.exp(lf), u)),
                                   bounds=(math.log(1e-4), math.log(1.0)), method="bounded",
                                   options={"xatol": 1e-10})
    f_peak = math.exp(res.x)
    assert f_peak == pytest.approx(math.sqrt(3.0) * u / 1200.0, rel=1e-4)  # 0.0200 Hz
    assert wind.DAVENPORT_LENGTH_M * f_peak / u == pytest.approx(math.sqrt(3.0), rel=1e-4)


@pytest.mark.parametrize("mean_speed", SPEEDS)
def test_numeric_integral_of_psd_is_6_kappa_u2(mean_speed: float) -> None:
    f = np.geomspace(1e-8, 1e8, 400001)
    integral = np.trapezoid(wind.davenport_psd(f, mean_speed), f)
    assert integral == pytest.approx(6 * 0.005 * mean_speed**2, rel=2e-3)  # tail above 1e8 Hz ~ 3e-5
    band = wind.davenport_band_variance(mean_speed, 1e-8, 1e8)
    assert band == pytest.approx(integral, rel=2e-3)


# --------------------------------------------------------------------------
# plot
# --------------------------------------------------------------------------
def test_plot_gust_psd_writes_png(tmp_path: Any) -> None:
    path = tmp_path / "gust_psd.png"
    out = wind.plot_gust_psd(U_50, np.random.default_rng(3), path, duration=3600.0, dt=0.1, nperseg=4096)
    assert out == str(path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
