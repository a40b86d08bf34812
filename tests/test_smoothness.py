"""The command's smoothness measures (dss14_env/core/smoothness.py) on signals whose answer is
known: white command changes, slow and fast sines, and the limiter-hit share."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dss14_env.core.smoothness import CUTOFF_HZ, high_frequency_share, limit_hit_pct

DT = 0.02  # the 50-Hz control period


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_white_change_has_the_flat_spectrum_share(seed: int) -> None:
    """A command whose change is white noise: the share above 5 Hz is that of a flat spectrum
    over 0-25 Hz, (25 - 5) / 25 = 0.8 (20,000 samples: the estimate scatters by about 0.01)."""
    command = np.cumsum(np.random.default_rng(seed).normal(size=20_000))
    flat = (0.5 / DT - CUTOFF_HZ) / (0.5 / DT)
    assert high_frequency_share(command, DT) == pytest.approx(flat, abs=0.04)


@pytest.mark.parametrize("freq_hz,low,high", [(0.2, 0.0, 0.01), (1.0, 0.0, 0.01), (8.0, 0.99, 1.0),
                                              (15.0, 0.99, 1.0)])
def test_a_sine_is_all_below_or_all_above(freq_hz: float, low: float, high: float) -> None:
    t = np.arange(3000) * DT
    assert low <= high_frequency_share(np.sin(2 * np.pi * freq_hz * t), DT) <= high


def test_the_share_scales_with_neither_the_amplitude_nor_an_offset() -> None:
    x = np.cumsum(np.random.default_rng(3).normal(size=2000))
    assert high_frequency_share(1e-6 * x + 5.0, DT) == pytest.approx(high_frequency_share(x, DT), rel=1e-9)


def test_too_short_or_constant_is_not_estimable() -> None:
    assert math.isnan(high_frequency_share(np.arange(10.0), DT))
    assert math.isnan(high_frequency_share(np.full(500, 0.1), DT))  # no change at all
    assert math.isnan(high_frequency_share(np.arange(500.0), DT))  # a constant change: no variance


def test_a_cutoff_beyond_nyquist_is_named() -> None:
    with pytest.raises(ValueError, match="cutoff_hz"):
        high_frequency_share(np.zeros(100), DT, cutoff_hz=30.0)


def test_several_axes_pool_their_spectra() -> None:
    """Two axes, shape (n, 2): the spectral densities are summed before the share is taken, so a
    slow axis beside a 10-Hz one of equal change power gives about half; two white axes give the
    flat spectrum's 0.8; two slow ones about 0."""
    t = np.arange(5000) * DT
    slow = np.sin(2 * np.pi * 0.5 * t) / (2 * np.sin(np.pi * 0.5 * DT))  # diff amplitude 1
    fast = np.sin(2 * np.pi * 10.0 * t) / (2 * np.sin(np.pi * 10.0 * DT))  # diff amplitude 1
    assert high_frequency_share(np.c_[slow, slow], DT) < 1e-3
    assert high_frequency_share(np.c_[fast, np.zeros_like(t)], DT) > 0.999
    assert high_frequency_share(np.c_[slow, fast], DT) == pytest.approx(0.5, abs=0.05)
    white = np.cumsum(np.random.default_rng(0).normal(size=(20_000, 2)), axis=0)
    assert high_frequency_share(white, DT) == pytest.approx(0.8, abs=0.04)
    assert math.isnan(high_frequency_share(np.zeros((100, 2)), DT))
    assert math.isnan(high_frequency_share(np.zeros((0, 2)), DT))
    with pytest.raises(ValueError, match=r"command: one axis \(n,\) or several \(n, k\)"):
        high_frequency_share(np.zeros((10, 2, 2)), DT)


def test_limit_hit_share_in_percent() -> None:
    assert limit_hit_pct(np.array([True, False, False, True])) == 50.0
    assert limit_hit_pct(np.zeros(7, bool)) == 0.0
    assert math.isnan(limit_hit_pct(np.zeros(0, bool)))
