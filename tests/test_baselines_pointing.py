"""The pointing-aware designs: the design model's pointing outputs (baselines/design.py) and the
pointing LQG against the PI on the dish's true pointing error (baselines/lqg.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dss14_env.baselines.design import (
    POINTING_OUTPUTS,
    default_controllers_config,
    reduce_rate_loop,
    rigid_pointing,
    static_deflection_map,
)
from dss14_env.baselines.lqg import PointingLQGController
from dss14_env.bench.runner import cell_rng, run
from dss14_env.core import stats
from dss14_env.model.assembly import default_model

#: a few short holds: 6 seeds of 20 s (5 s warm-up) per wind
SEEDS, STEPS = list(range(6)), 1000
HOLDS = ("hold_front", "hold_side")
DOMINANT = {"hold_front": "el", "hold_side": "xel"}


def rate_loop_response(f_hz: np.ndarray, outputs: tuple[str, ...], minus_rigid: bool = False) -> np.ndarray:
    """``[r_a, r_e, Tw_az, Tw_el] -> outputs`` of the full rate loop, computed directly; with
    ``minus_rigid`` the pointing outputs less ``S`` times the encoder angles (the deformation).
    """
    rl = default_model().rate_loop
    il, ol = list(rl.input_labels), list(rl.output_labels)
    A = np.asarray(rl.A)
    B = np.asarray(rl.B)[:, [il.index(s) for s in ("r_a", "r_e", "Tw_az", "Tw_el")]]
    C = np.asarray(rl.C)[[ol.index(s) for s in outputs]]
    if minus_rigid:
        xel_scale = math.cos(default_model().cfg.structure.elevation_angle)
        C = C - rigid_pointing(xel_scale) @ np.asarray(rl.C)[[ol.index("enc_az"), ol.index("enc_el")]]
    eye = np.eye(A.shape[0])
    return np.array([C @ np.linalg.solve(2j * math.pi * f * eye - A, B) for f in f_hz])


def reduced_pointing_response(order: int | None, f_hz: np.ndarray) -> np.ndarray:
    """The same map from a (reduced) split rate loop: ``S theta + deformation``."""
    red = reduce_rate_loop(order, pointing=True)
    S = rigid_pointing(red.xel_scale)
    eye = np.eye(red.A.shape[0])
    out = []
    for f in f_hz:
        s = 2j * math.pi * f
        X = np.linalg.solve(s * eye - red.A, red.B)
        out.append(S @ (red.C @ X + red.D) / s + red.Cd @ X + red.Dd)
    return np.array(out)


F_HZ = np.geomspace(0.01, 3.0, 60)


def test_full_order_pointing_equals_the_rate_loops() -> None:
    """The split (integrators + stable part + deformation) is an exact similarity: the pointing
    response of the full-order split equals the rate loop's own, to rounding.
    """
    G = rate_loop_response(F_HZ, POINTING_OUTPUTS)
    E = reduced_pointing_response(None, F_HZ) - G
    assert np.max(np.abs(E) / np.abs(G).max(axis=0)) < 1e-6


def test_pointing_order_keeps_the_pointing_response() -> None:
    """At the configured order the pointing response stays within 2 % of each channel's peak
    up to 3 Hz (the balanced-reduction error of the deformation outputs).
    """
    order = default_controllers_config().pointing.order
    G = rate_loop_response(F_HZ, POINTING_OUTPUTS)
    E = reduced_pointing_response(order, F_HZ) - G
    peak = np.abs(G).max(axis=0)
    main = [(0, 1), (1, 0), (0, 3), (1, 2)]  # el <- r_e, xel <- r_a, el <- Tw_el, xel <- Tw_az
    for o, i in main:
        assert np.max(np.abs(E[:, o, i])) < 0.02 * peak[o, i], (o, i)


def test_static_deflection_map_is_the_wind_torques() -> None:
    """``F d`` is the DC pointing of the rate loop under the torque that ``d`` stands for,
    with the encoders held (from the rate loop's own DC response, not the split's)."""
    G = rate_loop_response(np.array([1e-7]), ("enc_rate_az", "enc_rate_el"))[0].real
    P = rate_loop_response(np.array([1e-7]), POINTING_OUTPUTS, minus_rigid=True)[0].real
    T = np.array([3.0e5, 2.0e5])                       # N*m
    r = -np.linalg.solve(G[:, :2], G[:, 2:] @ T)       # holds the encoders still
    d = np.linalg.solve(G[:, :2], G[:, 2:] @ T)        # the command-level disturbance
    deflection = P[:, :2] @ r + P[:, 2:] @ T           # pointing with the encoders still
    assert np.allclose(static_deflection_map() @ d, deflection, rtol=1e-4)


@pytest.fixture(scope="module")
def holds() -> dict:
    ctrls = ["pi_kp1", "lqg", ("lqg_pointing", lambda env: PointingLQGController(env))]
    return run(ctrls, list(HOLDS), seeds=SEEDS, steps=STEPS, reference=None)


def _paired(res: dict, num: str, den: str, scenario: str, axis: str) -> stats.Ratio:
    eps = {c: {int(e["seed"]): e for e in res["episodes"] if e["controller"] == c
               and e["scenario"] == scenario} for c in (num, den)}
    seeds = sorted(set(eps[num]) & set(eps[den]))
    get = lambda c: [eps[c][s]["pointing_error_mdeg"][axis]["three_sigma"] for s in seeds]  # noqa: E731
    return stats.paired_ratios({axis: get(num)}, {axis: get(den)}, {axis: "rms"},
                               cell_rng(num, den, scenario))[axis]


@pytest.mark.parametrize("scenario", HOLDS)
def test_pointing_lqg_beats_the_pi_on_pointing(holds, scenario: str) -> None:
    """The pointing LQG's 3σ pointing error on the loaded axis is below the PI's, the paired
    95 % interval of the ratio excluding 1 (6 short holds)."""
    r = _paired(holds, "lqg_pointing", "pi_kp1", scenario, DOMINANT[scenario])
    assert r.high < 1.0, r


@pytest.mark.parametrize("scenario", HOLDS)
def test_pointing_lqg_takes_out_the_static_deflection(holds, scenario: str) -> None:
    """The mean wind torque's static deflection is corrected: the pointing LQG's mean pointing
    error on the loaded axis is below a third of the encoder LQG's (which holds the encoders
    on the command and leaves the deflection, ~2 mdeg at 50 km/h)."""
    ax = DOMINANT[scenario]
    mean = {c: abs(holds["summary"][c][scenario]["pointing_error_mdeg"][ax]["mean"]["value"])
            for c in ("lqg", "lqg_pointing")}
    assert mean["lqg"] > 1.0
    assert mean["lqg_pointing"] < mean["lqg"] / 3, mean
