"""Figures a reader can read: every trace visible and labelled (reproduce.py, bench/figures.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dss14_env.bench.figures import encoder_count_mdeg
from dss14_env.model.assembly import default_model
from dss14_env.model.calibration import reduction_scales
from dss14_env.model.reduction import hankel_singular_values
from dss14_env.reproduce import HANKEL_NOISE, wind_error_histories


def test_wind_error_histories_give_each_axis_its_panel_and_time_label() -> None:
    rng = np.random.default_rng(0)
    records = {"front": rng.normal(size=(200, 2)) * [0.03, 0.9],
               "side": rng.normal(size=(200, 2)) * [0.7, 0.2]}
    fig = wind_error_histories(records, dt=0.05)
    axes = fig.get_axes()
    assert len(axes) == 4
    for axp in axes:
        assert axp.get_xlabel() == "time, s" and len(axp.get_lines()) == 1
    # the small front-wind azimuth trace fills its own panel instead of hiding under elevation
    lo, hi = axes[0].get_ylim()
    assert hi - lo < 0.5


def test_one_encoder_count_is_the_20_bit_resolution() -> None:
    assert encoder_count_mdeg() == pytest.approx(360e3 / 2 ** 20)
    assert encoder_count_mdeg() == pytest.approx(0.343, abs=5e-4)


def test_hankel_noise_floor_is_far_below_the_kept_modes() -> None:
    """The floor only hides values double precision cannot resolve (Fig. 14): every kept
    flexible mode of the shipped model is drawn at its own value, well above the floor."""
    model = default_model()
    full = model.structure_full
    hsv = hankel_singular_values(full, **reduction_scales(model.cfg, full))
    flex = np.isfinite(hsv)
    floor = HANKEL_NOISE * np.max(hsv[flex])
    kept = hsv[[i for i in model.kept_modes if flex[i]]]
    assert kept.size > 0 and kept.min() > 10.0 * floor
    assert np.any(hsv[flex] < floor)  # the floor does hide the numerically-zero ones
