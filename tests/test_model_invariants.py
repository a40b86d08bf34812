"""Invariants of the model that follow from physics, through the public API.

The rate loop's DC gain (rate command -> encoder rate, free rigid load) is

    kappa * lam / (1 + lam),   lam = |G_t(0)| k_a / (D N_t),   kappa = |G_r/G_t| N_t / (N N_p)

(docs/model.md section 7, step 2): in steady state the load torque is zero, so the motor
torque is zero, the pressure only balances viscous friction and the valve flow only feeds the
motor's displacement; leakage, viscosity, k_s, k_p, bulk modulus and line volume drop out up
to the tiny viscous-friction term ``k_v (3 k_a2 + 2 (k_p + k_s) mu)`` next to ``2 D``
(about 2e-6 of it).  The loop gain ``lam`` does enter.  The expected values below are that
formula and its consequences; the DC gain itself is computed exactly from the assembled
60-state rate loop (:func:`dss14_env.model.analysis.dc_gain`).

Changing a hydraulic parameter here keeps the calibration (``DSS14Model(cfg, calibration)``),
so ``lam``, ``kappa`` and ``k_g`` stay; each changed parameter is shown to change the rate
loop's frequency response, so the DC invariance is not an unconnected parameter.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dss14_env.model import DSS14Model, default_model
from dss14_env.model.analysis import dc_gain
from dss14_env.model.linsys import freqresp

AXES = ["az", "el"]
CHANNEL = {"az": ("enc_rate_az", "r_a"), "el": ("enc_rate_el", "r_e")}
# [R] Eqs. (13)-(33) parameters that do not enter kappa lam / (1 + lam); "v_o" is per axis
LOSS_AND_LINE_PARAMS = ["k_a2", "mu", "k_s", "k_p", "beta", "v_o"]
FACTORS = [0.5, 2.0]
F_PROBE = np.geomspace(0.01, 50.0, 200)


@pytest.fixture(scope="module")
def model() -> DSS14Model:
    return default_model()


def _closed_form(m: DSS14Model, axis: str) -> float:
    lam, kappa = m.calibration.lam[axis], m.calibration.kappa[axis]
    return kappa * lam / (1.0 + lam)


def _dc(m: DSS14Model, axis: str) -> float:
    return dc_gain(m.rate_loop, *CHANNEL[axis])


def _with_hydraulics(m: DSS14Model, name: str, factor: float) -> DSS14Model:
    v = getattr(m.cfg.hydraulics, name)
    v = {k: x * factor for k, x in v.items()} if isinstance(v, dict) else v * factor
    return DSS14Model(m.cfg.replace(**{f"hydraulics__{name}": v}), m.calibration)


@pytest.mark.parametrize("axis", AXES)
def test_rate_loop_dc_is_kappa_lambda_over_one_plus_lambda(model: DSS14Model, axis: str) -> None:
    assert _dc(model, axis) == pytest.approx(_closed_form(model, axis), rel=1e-6)


@pytest.mark.parametrize("axis", AXES)
def test_dc_gain_helper_agrees_with_low_frequency_response(model: DSS14Model, axis: str) -> None:
    """The exact DC solve and the response at 1e-5 Hz (far below the board's 0.038 Hz lag
    pole) agree: the dropped rigid-body angle states do not reach the rate output."""
    h = abs(freqresp(model.rate_loop, [1e-5], *CHANNEL[axis])[0])
    assert h == pytest.approx(_dc(model, axis), rel=1e-6)


@pytest.mark.parametrize("factor", FACTORS)
@pytest.mark.parametrize("name", LOSS_AND_LINE_PARAMS)
def test_rate_loop_dc_does_not_depend_on_losses_or_lines(model: DSS14Model, name: str, factor: float) -> None:
    m2 = _with_hydraulics(model, name, factor)
    for axis in AXES:
        assert _dc(m2, axis) == pytest.approx(_dc(model, axis), rel=1e-5), axis
        # ... while the parameter does change the rate loop at some frequency
        h0 = freqresp(model.rate_loop, F_PROBE, *CHANNEL[axis])
        h2 = freqresp(m2.rate_loop, F_PROBE, *CHANNEL[axis])
        assert np.max(np.abs(h2 / h0 - 1.0)) > 5e-4, axis


@pytest.mark.parametrize("factor", FACTORS)
@pytest.mark.parametrize("axis", AXES)
def test_rate_loop_dc_moves_with_loop_gain(model: DSS14Model, axis: str, factor: float) -> None:
    c = model.calibration
    lam = dict(c.lam, **{axis: c.lam[axis] * factor})
    m2 = DSS14Model(model.cfg, dataclasses.replace(c, lam=lam))
    lam2, kappa = lam[axis], c.kappa[axis]
    dc2 = _dc(m2, axis)
    assert abs(dc2 / _dc(model, axis) - 1.0) > 0.01
    assert dc2 == pytest.approx(kappa * lam2 / (1.0 + lam2), rel=1e-6)
    # the other axis is untouched (up to the 1e-3 az-el coupling, which does not act at DC)
    other = "el" if axis == "az" else "az"
    assert _dc(m2, other) == pytest.approx(_dc(model, other), rel=1e-9)
