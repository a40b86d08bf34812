"""Tests of the Ka-band wind envelope (:mod:`dss14_env.bench.envelope`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dss14_env.bench.envelope import (
    KA_RMS_MDEG,
    X_RMS_MDEG,
    band_envelopes,
    crossing_speed,
    envelope,
    envelope_table,
)


@pytest.mark.parametrize(("rms", "mean_radial"), [(KA_RMS_MDEG, 1.54), (X_RMS_MDEG, 8.0)])
def test_per_axis_requirement_gives_the_mean_radial_requirement(rms: float, mean_radial: float) -> None:
    # two independent zero-mean Gaussian axes of this rms: their radial error's mean, sampled
    n = 200_000
    r = np.hypot(*np.random.default_rng(3).normal(0.0, rms, (2, n)))
    half = 4.0 * r.std() / math.sqrt(n)
    assert abs(r.mean() - mean_radial) < half


@pytest.mark.parametrize(("worst", "expected"), [
    ([1.3, 1.4, 1.5], (30.0, "below")),
    ([0.5, 0.6, 0.7], (50.0, "above")),
    ([0.8, 1.0, 1.4], (45.0, "within")),
    ([0.8, 1.3, 1.0], (38.0, "within")),  # the first crossing, not a later dip
])
def test_crossing_speed(worst: list[float], expected: tuple[float, str]) -> None:
    v, where = crossing_speed([30.0, 40.0, 50.0], worst, 1.2)
    assert where == expected[1] and v == pytest.approx(expected[0], abs=1e-12)


def _episodes(rms_by_speed: dict[float, tuple[float, float]], n: int, spread: float = 0.0, seed: int = 0
              ) -> dict[float, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {v: np.array(r) * (1.0 + spread * rng.standard_normal((n, 1))) for v, r in rms_by_speed.items()}


def test_envelope_per_direction_and_worst() -> None:
    front = _episodes({30.0: (0.5, 0.1), 50.0: (1.0, 0.1), 70.0: (1.6, 0.2)}, 8)
    side = _episodes({30.0: (0.2, 0.9), 50.0: (0.3, 1.5), 70.0: (0.4, 2.0)}, 8)
    e = envelope({"front": front, "side": side}, 1.2, np.random.default_rng(0), n_resamples=50)
    assert e["front"]["envelope_kmh"]["value"] == pytest.approx(50.0 + 20.0 * 0.2 / 0.6)
    assert e["side"]["envelope_kmh"]["value"] == pytest.approx(30.0 + 20.0 * 0.3 / 0.6)
    assert e["worst"]["direction"] == "side"
    # identical episodes: no scatter, a degenerate interval
    assert e["worst"]["envelope_kmh"]["ci95"] == pytest.approx([40.0, 40.0])
    assert e["front"]["rms_mdeg"]["el"] == pytest.approx([0.5, 1.0, 1.6])


def test_envelope_interval_holds_the_value_with_scattered_episodes() -> None:
    pts = {"front": _episodes({30.0: (0.6, 0.1), 50.0: (1.0, 0.1), 70.0: (1.6, 0.2)}, 32, spread=0.15)}
    e = envelope(pts, 1.2, np.random.default_rng(1), n_resamples=400)["front"]["envelope_kmh"]
    assert e["ci95"][0] < e["value"] < e["ci95"][1]


def test_band_envelopes_from_runner_episodes_and_table() -> None:
    eps = []
    for scen, rms in (("hold_front", 1.0), ("hold_front_70kmh", 1.4), ("track", 9.0)):
        for seed in range(4):
            eps.append({"controller": "c", "scenario": scen, "seed": seed,
                        "pointing_error_mdeg": {"el": {"rms": rms}, "xel": {"rms": 0.1}}})
    eps.append({"controller": "c", "scenario": "hold_front", "seed": 9,
                "pointing_error_mdeg": {"el": {"rms": math.nan}, "xel": {"rms": 0.1}}})  # left out
    out = band_envelopes(eps, [("hold_front", "front", 50.0), ("hold_front_70kmh", "front", 70.0)],
                         n_resamples=20)
    ka = out["controllers"]["c"]["Ka"]["front"]
    assert ka["envelope_kmh"]["where"] == "within"
    assert ka["envelope_kmh"]["value"] == pytest.approx(50.0 + 20.0 * (KA_RMS_MDEG - 1.0) / 0.4)
    assert out["controllers"]["c"]["X"]["front"]["envelope_kmh"]["where"] == "above"
    table = envelope_table(out)
    assert "| c |" in table and ">70" in table
