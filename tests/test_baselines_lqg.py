"""LQG design (Riccati residuals, closed-loop analysis of baselines/analysis.py) and the LQG and
yardstick controllers against the environment (baselines/lqg.py, baselines/yardstick.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dss14_env.baselines.analysis import (
    closed_loop,
    lqg_as_linear,
    pi_as_linear,
    riccati_cost,
    sampled_three_sigma_mdeg,
    stationary_performance,
)
from dss14_env.baselines.design import build_design_model
from dss14_env.baselines.interface import ControlInterface, Weights
from dss14_env.baselines.lqg import EstimatorController, LQGController, lqg_design_from_config
from dss14_env.baselines.pi import PIController
from dss14_env.baselines.yardstick import (
    YardstickController,
    expected_performance,
    pi_performance,
    yardstick_design,
)
from dss14_env.bench.runner import run
from dss14_env.core.units import AXES, KMH, WIND_DIRECTIONS
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.plant import get_plant

U50 = 50 * KMH
DOMINANT = {"front": 1, "side": 0}  # el in front wind, az in side wind


@pytest.fixture(scope="module")
def spec() -> ControlInterface:
    return ControlInterface.default()


@pytest.fixture(scope="module")
def designs(spec) -> dict:
    return {"direction-free": lqg_design_from_config(spec),
            "front": lqg_design_from_config(spec, wind=(U50, "front")),
            "side": lqg_design_from_config(spec, wind=(U50, "side"))}


@pytest.fixture(scope="module")
def plants(spec) -> dict:
    """Full-order nominal plant models (64 states) of the two Table-4 winds."""
    return {d: build_design_model(spec.dt, order=None, wind=(U50, d)) for d in ("front", "side")}


# ------------------------------------------------------------------ Riccati equations
@pytest.mark.parametrize("which", ["direction-free", "front", "side"])
@pytest.mark.parametrize("equation", ["lqr", "kalman"])
def test_riccati_residuals_small(designs, which: str, equation: str) -> None:
    assert designs[which].residuals[equation] < 1e-9


@pytest.mark.parametrize("direction", ["front", "side"])
@pytest.mark.parametrize("equation", ["lqr", "kalman"])
def test_yardstick_riccati_residuals_small(spec, direction: str, equation: str) -> None:
    assert yardstick_design(spec, U50, direction).residuals[equation] < 1e-9


# ------------------------------------------------------------------ stability
@pytest.mark.parametrize("which", ["direction-free", "front", "side"])
def test_lqr_and_estimator_stable_on_the_design_model(designs, which: str) -> None:
    d = designs[which]
    assert np.max(np.abs(np.linalg.eigvals(d.Az - d.Bz @ d.K))) < 1.0
    n, nd = d.dm.n, d.n_d
    Ae = np.eye(n + nd)
    Ae[:n, :n] = d.dm.Ad
    Ae[:n, n:] = d.dm.Bd
    Ce = np.hstack([d.dm.C, np.zeros((2, nd))])
    assert np.max(np.abs(np.linalg.eigvals(Ae @ (np.eye(n + nd) - d.L @ Ce)))) < 1.0


@pytest.mark.parametrize("which", ["direction-free", "front", "side"])
@pytest.mark.parametrize("direction", ["front", "side"])
def test_reduced_lqg_stabilises_the_full_order_nominal_plant(designs, plants, which, direction) -> None:
    """Eigenvalues of the interconnection of the 64-state plant with the reduced-order LQG."""
    cl = closed_loop(plants[direction], lqg_as_linear(designs[which]))
    assert cl.spectral_radius() < 1.0


@pytest.mark.parametrize("direction", ["front", "side"])
def test_yardstick_cost_from_riccati_equals_lyapunov(spec, direction: str) -> None:
    d = yardstick_design(spec, U50, direction)
    perf = stationary_performance(closed_loop(d.dm, lqg_as_linear(d)), spec.weights)
    assert riccati_cost(d) == pytest.approx(perf["cost"], rel=1e-3)


@pytest.mark.parametrize("direction", ["front", "side"])
@pytest.mark.parametrize("which", ["direction-free", "front", "side"])
def test_no_reduced_lqg_beats_the_yardstick_on_its_cost(spec, designs, plants, direction, which) -> None:
    """On the yardstick's own (linear, white-quantisation) problem its cost is the minimum."""
    y = expected_performance(spec, U50, direction)
    other = stationary_performance(closed_loop(plants[direction], lqg_as_linear(designs[which])),
                                   spec.weights)
    assert other["cost"] >= y["cost"] * (1 - 1e-6)


@pytest.mark.parametrize("direction", ["front", "side"])
def test_lqg_within_1p2_of_the_yardstick_on_its_own_problem(spec, designs, plants, direction) -> None:
    """The yardstick's optimality claim lives on the linear, white-quantisation model; there the
    reduced-order LQG (designed for the direction) is within 1.2x of it on the dominant axis."""
    ax = DOMINANT[direction]
    y = expected_performance(spec, U50, direction)["three_sigma_mdeg"][ax]
    lqg = stationary_performance(closed_loop(plants[direction], lqg_as_linear(designs[direction])),
                                 spec.weights)["three_sigma_mdeg"][ax]
    assert y < lqg <= 1.2 * y


def test_stationary_performance_refuses_an_unstable_loop(plants, designs) -> None:
    d = designs["front"]
    bad = lqg_as_linear(d)
    bad = type(bad)(bad.Ac, bad.Bc, -50 * bad.Cc, -50 * bad.Dc)
    with pytest.raises(ValueError, match="unstable"):
        stationary_performance(closed_loop(plants["front"], bad), Weights(1e-4, 1e-3, 1.0))


# ------------------------------------------------------------------ against the environment
@pytest.fixture(scope="module")
def hold_results() -> dict:
    """PI, LQG, MPC and the yardstick on the same 2 seeds x 30 s of 50 km/h front/side wind."""
    return run(["pi_kp1", "lqg", "mpc", "yardstick"], ["hold_front", "hold_side"], seeds=[0, 1],
               steps=1500)["summary"]


def _three_sigma(summary: dict, ctrl: str, direction: str) -> float:
    ax = AXES[DOMINANT[direction]]
    return summary[ctrl][f"hold_{direction}"]["servo_error_mdeg"][ax]["three_sigma"]["median"]


@pytest.mark.parametrize("ctrl", ["lqg", "mpc"])
@pytest.mark.parametrize("direction", ["front", "side"])
def test_half_of_pi_on_the_dominant_axis(hold_results, ctrl: str, direction: str) -> None:
    pi = _three_sigma(hold_results, "pi_kp1", direction)
    assert _three_sigma(hold_results, ctrl, direction) <= 0.5 * pi


@pytest.mark.parametrize("ctrl", ["lqg", "mpc"])
@pytest.mark.parametrize("direction", ["front", "side"])
def test_within_2x_of_the_analytic_yardstick(hold_results, spec, ctrl: str, direction: str) -> None:
    """The analytic yardstick (Riccati/Lyapunov) does not depend on the BLAS kernel.

    Measured ratios (LQG and MPC) on these 2 seeds x 30 s: front 1.29-1.43, side 1.53-1.69
    (OpenBLAS Haswell, SkylakeX and Sandybridge kernels); the default bench's 128 episodes
    give 1.33 and 1.84 [1.77, 1.91].  The bound 2 leaves the scatter of 2 short episodes room.
    """
    analytic = expected_performance(spec, U50, direction)["three_sigma_mdeg"][DOMINANT[direction]]
    assert _three_sigma(hold_results, ctrl, direction) <= 2.0 * analytic


@pytest.mark.parametrize("ctrl", ["lqg", "mpc"])
def test_within_1p3_of_the_simulated_yardstick_in_side_wind(hold_results, ctrl: str) -> None:
    """Same plant, gusts and quantised encoder.  Measured LQG ratio 1.11-1.20, MPC 1.05-1.19
    on these 2 seeds x 30 s (Haswell, SkylakeX and Sandybridge kernels): the bound 1.3 is above
    that scatter.  Front wind is not compared: the simulated yardstick has no anti-windup and on
    some kernels (SkylakeX, seed 0) its elevation command rings up on the acceleration limit
    after ~22 s, so its front-wind figure is not a reference there.
    """
    yardstick = _three_sigma(hold_results, "yardstick", "side")
    assert _three_sigma(hold_results, ctrl, "side") <= 1.3 * yardstick


def test_pi_reproduces_table4_in_the_runner(hold_results) -> None:
    assert 2.0 <= _three_sigma(hold_results, "pi_kp1", "front") <= 3.2
    assert 1.6 <= _three_sigma(hold_results, "pi_kp1", "side") <= 2.6


@pytest.fixture(scope="module")
def step_results() -> dict:
    return run(["pi_kp1", "lqg", "mpc"], ["step"], seeds=[0], steps=750)["summary"]


@pytest.mark.parametrize("ctrl", ["lqg", "mpc"])
@pytest.mark.parametrize("axis", AXES)
def test_step_overshoot_and_settling(step_results, ctrl: str, axis: str) -> None:
    s = step_results[ctrl]["step"]["step"][axis]
    pi = step_results["pi_kp1"]["step"]["step"][axis]
    assert s["overshoot_pct"]["max"] <= 10.0
    assert s["settling_time_s"]["max"] < pi["settling_time_s"]["min"]


def test_lqg_starts_bumplessly() -> None:
    env = DSS14Env(scenario="hold", wind_speed_kmh=50.0, wind_direction="side")
    obs, _ = env.reset(seed=3)
    ctrl = LQGController(env)
    ctrl.reset(3)
    a = ctrl.act(obs)
    assert a == pytest.approx(obs[10:12], abs=1e-6)


@pytest.mark.parametrize("direction", ["front", "side"])
def test_lqg_infers_the_wind_direction_from_the_start_command(direction: str) -> None:
    env = DSS14Env(scenario="hold", wind_speed_kmh=50.0, wind_direction=direction)
    obs, _ = env.reset(seed=0)
    ctrl = LQGController(env)
    ctrl.reset(0)
    ctrl.act(obs)
    assert ctrl.info["design_wind"][1] == pytest.approx(WIND_DIRECTIONS[direction])


def test_lqg_without_wind_uses_the_direction_free_model() -> None:
    env = DSS14Env(scenario="step", wind_speed_kmh=0.0)
    obs, _ = env.reset(seed=0)
    ctrl = LQGController(env)
    ctrl.reset(0)
    ctrl.act(obs)
    assert ctrl.info["design_wind"] is None


@pytest.mark.parametrize("bad, match", [(np.zeros(5, np.float32), r"observation must have shape \(12,\)"),
                                        (np.full(12, np.nan), "observation must be finite")])
def test_bad_observation_is_refused(bad: np.ndarray, match: str) -> None:
    ctrl = LQGController(None)
    with pytest.raises(ValueError, match=match):
        ctrl.act(bad)


def test_design_period_must_match_the_env() -> None:
    d = lqg_design_from_config(ControlInterface.default())
    with pytest.raises(ValueError, match="period"):
        EstimatorController(d, ControlInterface.default(dt=0.01), "x")


def test_yardstick_follows_the_episode_wind() -> None:
    ctrl = YardstickController(None)
    ctrl.set_scenario(U50, WIND_DIRECTIONS["side"])
    env = DSS14Env(scenario="hold", wind_speed_kmh=50.0, wind_direction="side")
    obs, _ = env.reset(seed=0)
    ctrl.reset(0)
    ctrl.act(obs)
    assert ctrl.design.dm.wind == (U50, WIND_DIRECTIONS["side"])
    assert ctrl.design.dm.n == 64


@pytest.mark.parametrize("direction", ["front", "side"])
def test_yardstick_expected_error_is_below_pi(direction: str) -> None:
    y = expected_performance(None, U50, direction)
    pi = sampled_three_sigma_mdeg(get_plant(U50, 0.02), WIND_DIRECTIONS[direction])
    k = DOMINANT[direction]
    assert 0 < y["three_sigma_mdeg"][k] < 0.25 * pi[k]


@pytest.mark.parametrize("direction", ["front", "side"])
def test_pi_as_linear_is_the_sampled_pi(spec, direction: str) -> None:
    """The PI as a linear controller on the full design model (exact encoders) has the stationary
    3σ of the sampled PI loop on the environment's plant (an independent state-space form)."""
    dm = build_design_model(spec.dt, order=None, wind=(U50, direction), bits=None, pointing=True)
    perf = stationary_performance(closed_loop(dm, pi_as_linear(spec.dt)), spec.weights)
    pi = sampled_three_sigma_mdeg(get_plant(U50, spec.dt), WIND_DIRECTIONS[direction])
    assert perf["three_sigma_mdeg"] == pytest.approx(pi.tolist(), rel=1e-4)


@pytest.mark.parametrize("direction", ["front", "side"])
def test_pi_performance_is_on_the_yardsticks_statistic(spec, direction: str) -> None:
    """The PI's figures for the reference ratios come from the yardsticks' own model (its 20-bit
    quantisation noise included): within 2 % of the exact-encoder sampled PI, and above the
    pointing yardstick's pointing error on the loaded axis."""
    pi = pi_performance(spec, U50, direction)
    exact = sampled_three_sigma_mdeg(get_plant(U50, spec.dt), WIND_DIRECTIONS[direction])
    k = DOMINANT[direction]
    assert pi["three_sigma_mdeg"][k] == pytest.approx(exact[k], rel=0.02)
    assert pi["error"] == "pi" and pi["action_change"] is None
    y = expected_performance(spec, U50, direction, "pointing")
    pk = 1 - k  # pointing axes are [el, xel]: el in front wind, xel in side wind
    assert y["pointing_three_sigma_mdeg"][pk] < pi["pointing_three_sigma_mdeg"][pk]


def test_pi_controller_is_used_from_the_env_helper() -> None:
    """The runner's PI is the report's (kp 1, ki 0.3) controller of baselines/pi.py."""
    env = DSS14Env(scenario="hold")
    assert PIController(env, "kp1").kp == pytest.approx([1.0, 1.0])
