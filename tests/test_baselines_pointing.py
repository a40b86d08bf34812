"""The pointing-aware designs: the design model's pointing outputs (baselines/design.py) and the
pointing LQG against the PI on the dish's true pointing error (baselines/lqg.py)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dss14_env.baselines.analysis import closed_loop, lqg_as_linear, stationary_performance
from dss14_env.baselines.design import (
    POINTING_OUTPUTS,
    build_design_model,
    default_controllers_config,
    reduce_rate_loop,
    rigid_pointing,
    static_deflection_map,
)
from dss14_env.baselines.interface import ControlInterface
from dss14_env.baselines.lqg import PointingLQGController, lqg_design_from_config
from dss14_env.baselines.mpc import PointingMPCController
from dss14_env.baselines.yardstick import (
    ERROR_ONLY_WEIGHT,
    MATCH_BRACKET,
    PointingYardstickController,
    acceleration_matched,
    error_only_limit,
    expected_performance,
)
from dss14_env.bench.runner import POINTING_AXES, cell_rng, run
from dss14_env.core import stats
from dss14_env.core.units import KMH
from dss14_env.model.assembly import default_model
from dss14_env.wind.loads import direction_angle

U50 = 50 * KMH

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


@pytest.fixture(scope="module")
def mpc_holds() -> dict:
    """The pointing MPC (one episode at a time) and the PI on 4 short holds per wind."""
    ctrls = ["pi_kp1", ("mpc_pointing", lambda env: PointingMPCController(env))]
    return run(ctrls, list(HOLDS), seeds=SEEDS[:4], steps=STEPS, reference=None)


@pytest.mark.parametrize("ctrl", ["lqg_pointing", "mpc_pointing"])
@pytest.mark.parametrize("scenario", HOLDS)
def test_pointing_controllers_beat_the_pi_on_pointing(holds, mpc_holds, ctrl: str, scenario: str) -> None:
    """The pointing LQG's and MPC's 3σ pointing error on the loaded axis is below the PI's, the
    paired 95 % interval of the ratio excluding 1 (6 / 4 short holds), and the MPC never fell
    back to the LQG law."""
    res = holds if ctrl == "lqg_pointing" else mpc_holds
    r = _paired(res, ctrl, "pi_kp1", scenario, DOMINANT[scenario])
    assert r.high < 1.0, r
    assert res["summary"][ctrl][scenario]["fallbacks"] == 0


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


# ------------------------------------------------------------------ the yardsticks
@pytest.fixture(scope="module")
def spec() -> ControlInterface:
    return ControlInterface.default()


@pytest.mark.parametrize("direction", ["front", "side"])
def test_each_yardstick_is_best_on_its_own_cost(spec, direction: str) -> None:
    """The pointing yardstick has the smallest ``J_point`` and the encoder yardstick the
    smallest ``J_enc`` of the two; the pointing LQG (reduced order, integrator, other weights)
    has a larger ``J_point`` than the pointing yardstick on the full model."""
    enc = expected_performance(spec, U50, direction, "encoder")
    pt = expected_performance(spec, U50, direction, "pointing")
    assert pt["cost_pointing"] < enc["cost_pointing"]
    assert enc["cost"] < pt["cost"]
    design = lqg_design_from_config(spec, wind=(U50, direction_angle(direction)),
                                    pointing=default_controllers_config().pointing)
    plant = build_design_model(spec.dt, order=None, wind=(U50, direction), pointing=True)
    lqg = stationary_performance(closed_loop(plant, lqg_as_linear(design)), spec.weights)
    assert lqg["cost_pointing"] > pt["cost_pointing"]


@pytest.mark.parametrize("direction, axis", [("front", 1), ("side", 0)])
def test_a_yardstick_bounds_its_cost_not_the_3sigma(spec, direction: str, axis: int) -> None:
    """With a 1000x smaller action-change weight the encoder design has a SMALLER 3σ servo
    error on the loaded axis than the encoder yardstick (docs/controllers.md's yardsticks table:
    0.279 / 0.118 against 0.386 / 0.136 mdeg on the shipped drive) and a larger benchmark
    cost: the yardstick bounds J, not the 3σ."""
    yard = expected_performance(spec, U50, direction, "encoder")
    cheap = expected_performance(spec, U50, direction, "encoder", action_change=1e-3)
    assert cheap["three_sigma_mdeg"][axis] < 0.95 * yard["three_sigma_mdeg"][axis]
    assert cheap["cost"] > yard["cost"]


@pytest.mark.parametrize("direction, axis", [("front", 1), ("side", 0)])
def test_the_encoders_error_only_limit_has_converged(spec, direction: str, axis: int) -> None:
    """The encoder yardstick's error-only limit: 100x smaller weight changes its loaded-axis 3σ
    by < 2 %, while the acceleration it needs is far beyond the limiter's 0.2 deg/s^2."""
    lim = error_only_limit(spec, U50, direction, "encoder")
    finer = expected_performance(spec, U50, direction, "encoder", ERROR_ONLY_WEIGHT / 100)
    assert lim["three_sigma_mdeg"][axis] == pytest.approx(finer["three_sigma_mdeg"][axis], rel=0.02)
    assert max(lim["accel_three_sigma_deg_s2"]) > 5 * lim["accel_limit_deg_s2"]


def test_acceleration_matched_brackets_the_limit(spec) -> None:
    """The matched pointing yardstick (front wind) needs at most the limit's acceleration, and
    one bracket step below its weight more: the bisection keeps the limit between its ends."""
    it = 4
    m = acceleration_matched(spec, U50, "front", "pointing", iterations=it)
    lo, hi = (math.log(x) for x in MATCH_BRACKET)
    step = math.exp((hi - lo) / 2 ** it)
    below = expected_performance(spec, U50, "front", "pointing", m["action_change"] / step)
    assert max(m["accel_three_sigma_deg_s2"]) <= m["accel_limit_deg_s2"]
    assert max(below["accel_three_sigma_deg_s2"]) > m["accel_limit_deg_s2"]


@pytest.mark.parametrize("scenario, axis", [("hold_front", "el"), ("hold_side", "xel")])
def test_pointing_yardstick_analytic_within_the_simulations_ci(pointing_yardstick_runs, scenario: str,
                                                               axis: str) -> None:
    """On the yardstick's own problem -- 24-bit encoders, whose quantisation error is close to
    white at these errors, and the acceleration limit opened (the model has no limiter) -- the
    simulated pointing yardstick's pooled 3σ pointing error has the analytic figure inside its
    95 % interval (16 holds of 30 s).  With the 20-bit encoders and the limiter the simulated
    figure is above the analytic one (docs/controllers.md 10)."""
    res = pointing_yardstick_runs
    cell = res["summary"]["yardstick_pointing"][scenario]["pointing_error_mdeg"][axis]["three_sigma"]
    analytic = res["yardstick"][scenario]["pointing"]["pointing_three_sigma_mdeg"][POINTING_AXES.index(axis)]
    assert cell["ci95"][0] <= analytic <= cell["ci95"][1], (cell, analytic)


@pytest.fixture(scope="module")
def pointing_yardstick_runs() -> dict:
    return run([("yardstick_pointing", PointingYardstickController)], list(HOLDS), seeds=list(range(16)),
               steps=1500, env_kwargs={"encoder_bits": 24, "accel_limit_deg_s2": 100.0}, reference=None)


# ------------------------------------------------------------------ axis encoders
def test_axis_encoder_design_measures_the_axis_angles() -> None:
    """With ``encoders="axis"`` the design model's measurement is the structure's angle at the
    axes, ``S^-1`` times its pointing, and a command-level disturbance shows in it as the
    static deflection (drive encoders: not at all)."""
    dt = ControlInterface.default().dt
    axis = build_design_model(dt, order=None, encoders="axis")
    drive = build_design_model(dt, order=None, pointing=True)
    S = rigid_pointing(axis.xel_scale)
    assert np.allclose(S @ axis.C, axis.Cp, atol=1e-12 * np.abs(axis.Cp).max())
    assert np.allclose(axis.Cp, drive.Cp)
    assert np.allclose(S @ axis.disturbance_measurement(), static_deflection_map())
    assert not drive.disturbance_measurement().any()


@pytest.fixture(scope="module")
def axis_holds() -> dict:
    ctrls = ["pi_kp1", "lqg", ("lqg_pointing", lambda env: PointingLQGController(env))]
    return run(ctrls, list(HOLDS), seeds=SEEDS[:4], steps=STEPS, env_kwargs={"encoders": "axis"},
               reference=None)


@pytest.mark.parametrize("ctrl", ["lqg", "lqg_pointing"])
@pytest.mark.parametrize("scenario", HOLDS)
def test_designs_on_axis_encoders_beat_the_pi_on_them(axis_holds, ctrl: str, scenario: str) -> None:
    """The encoder and pointing LQGs designed for axis encoders (read from the environment's
    configuration) point better than the PI on the same axis encoders, paired 95 % interval
    below 1 (4 short holds), no episode terminates, and neither rides the acceleration limit
    (the encoder LQG with its drive-encoder action-change weight clipped 97 % of the steps)."""
    r = _paired(axis_holds, ctrl, "pi_kp1", scenario, DOMINANT[scenario])
    assert r.high < 1.0, r
    assert axis_holds["summary"][ctrl][scenario]["terminated"] == 0
    hits = [e["smoothness"]["accel_limit_hits_pct"] for e in axis_holds["episodes"]
            if e["controller"] == ctrl and e["scenario"] == scenario]
    assert max(hits) < 2.0, hits


def test_yardsticks_table_is_the_committed_results() -> None:
    """docs/controllers.md's yardsticks table is the rendering of docs/results/yardsticks.json."""
    script = Path(__file__).resolve().parents[1] / "scripts" / "yardsticks.py"
    assert subprocess.run([sys.executable, str(script), "--check"], capture_output=True).returncode == 0


def test_pointing_wind_speed_table_is_the_committed_results() -> None:
    """docs/controllers.md's pointing-vs-wind-speed tables are the rendering of
    docs/results/pointing_wind_speed.json."""
    script = Path(__file__).resolve().parents[1] / "scripts" / "pointing_wind_speed.py"
    assert subprocess.run([sys.executable, str(script), "--check"], capture_output=True).returncode == 0
