"""Lead (plus notch) position-loop designs (dss14_env/model/lead_design.py, reproduce's
``lead_pm45_*`` rows): each design is re-checked here on its own, on a finer frequency grid and
with python-control's closed loop, against the criteria it claims (phase margin >= 45 deg,
peak sensitivity <= 2, stable), and against the PI it extends.
"""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

from dss14_env import reproduce as rep
from dss14_env.core.units import AXES
from dss14_env.model import default_model
from dss14_env.model.lead_design import lead_design, lead_tf
from dss14_env.model.linsys import freqresp

#: a grid 4x finer than the design's, to 60 Hz
FINE = np.geomspace(0.005, 60.0, 8000)


@pytest.fixture(scope="module")
def designs() -> dict:
    m = default_model()
    kp, ki = m.gains("kp1")
    out = {}
    for enc in ("drive", "axis"):
        outs, scale = rep.measured_angles(m, enc)
        for k, ax in enumerate(AXES):
            d = lead_design(m.rate_loop, ax, outs, (scale[0], scale[1]), (kp[1 - k], ki[1 - k]), enc)
            out[enc, ax] = (d, outs, scale)
    return out


@pytest.mark.parametrize("enc", ["drive", "axis"])
@pytest.mark.parametrize("ax", AXES)
def test_design_meets_its_criteria_on_a_finer_grid(designs, enc: str, ax: str) -> None:
    d, outs, scale = designs[enc, ax]
    assert d is not None and d.axis == ax and d.encoders == enc
    m = default_model()
    k = AXES.index(ax)
    g = freqresp(m.rate_loop, FINE, outs[k], ("r_a", "r_e")[k]) * scale[k]
    L = np.asarray(d.controller(2j * np.pi * FINE), complex).reshape(-1) * g
    mag = np.abs(L)
    i = int(np.flatnonzero(mag < 1.0)[0])
    assert FINE[i - 1] <= d.crossover_hz * 1.01 and FINE[i] >= d.crossover_hz * 0.99
    phase = np.degrees(np.unwrap(np.angle(L)))
    phase -= 360.0 * np.ceil(phase[0] / 360.0)
    assert 180.0 + phase[i] >= 45.0 - 1.0  # the crossover's phase, to the grid's step
    assert np.max(1.0 / np.abs(1.0 + L)) <= 2.0 * 1.02  # a peak between the design's grid points


@pytest.mark.parametrize("enc", ["drive", "axis"])
@pytest.mark.parametrize("ax", AXES)
def test_design_closes_a_stable_loop(designs, enc: str, ax: str) -> None:
    """Both axes closed (the other by the report's PI), built here with control.interconnect."""
    d, outs, scale = designs[enc, ax]
    m = default_model()
    kp, ki = m.gains("kp1")
    k = AXES.index(ax)
    rl = m.rate_loop
    rows = [rl.output_labels.index(o) for o in outs]
    cols = [rl.input_labels.index(i) for i in ("r_a", "r_e")]
    plant = ct.ss(rl.A, rl.B[:, cols], np.diag(scale) @ rl.C[rows], 0, inputs=["u0", "u1"],
                  outputs=["y0", "y1"], name="plant")
    ctrls = [ct.tf2ss(d.controller if i == k else ct.tf([kp[i], ki[i]], [1, 0]), inputs=f"e{i}",
                      outputs=f"u{i}", name=f"c{i}") for i in range(2)]
    errs = [ct.summing_junction(inputs=[f"-y{i}"], output=f"e{i}", name=f"s{i}") for i in range(2)]
    cl = ct.interconnect([plant, *ctrls, *errs], inplist=[], outlist=["y0", "y1"])
    assert np.max(np.linalg.eigvals(cl.A).real) < 0


@pytest.mark.parametrize("ax", AXES)
def test_lead_reaches_beyond_the_highest_gain_pi(designs, ax: str) -> None:
    """With the drive encoders the lead's crossover is above that of the highest-gain PI keeping
    45 deg and a stable loop (reproduce's ``pi_pm45`` rows).  On the stiff shipped drive the PI
    reaches further than on the old one and the lead's lead shrank to 1.23x (az) and 1.14x (el)
    the PI's crossover (measured), so the claim is "above", not "1.5x above"."""
    pi = rep.highest_gain_loop(default_model(), "drive", ax)["crossover_hz"]
    lead = designs["drive", ax][0].crossover_hz
    assert lead > 1.1 * pi, (lead, pi)


def test_lead_tf_has_its_phase_at_the_crossover() -> None:
    """The lead factor alone gives its phase at the crossover (the PI and notch factors away)."""
    c = lead_tf(0.5, 45.0, 1e9)  # the PI zero out of the way
    w = 2 * math.pi * 0.5
    assert math.degrees(np.angle(complex(c(1j * w)))) == pytest.approx(45.0, abs=0.01)
