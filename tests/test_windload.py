"""Wind loads, the Table 4 calibration and the exact discretisation helpers.

Table 4 values are the report's and the accepted ranges the project's, typed here.  The four
moment coefficients are solved so the exact 50 km/h figures equal Table 4: the test named
``test_regression_calibrated_*`` re-checks that (a regression check of the calibration, not
evidence).  The consequences the calibration does not set -- the time-domain simulation, the
figures at 30 and 70 km/h, their scaling with speed -- are computed by routes that do not share
code with :func:`three_sigma_mdeg` (numerical PSD integral of the Davenport *formula*; a seeded
simulation of the exactly discretised loop) or checked against the load model's scaling laws.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, linalg, signal

from dss14_env.core.schema import ConfigError
from dss14_env.core.units import rad_to_mdeg
from dss14_env.model.assembly import default_model
from dss14_env.model.linsys import balance, discretize, freqresp, noise_factor
from dss14_env.wind.gusts import davenport_psd, filter_variance
from dss14_env.wind.loads import (
    WindLoads,
    augment_with_wind,
    default_wind_loads,
    direction_angle,
    load_wind_config,
    simulate_wind_response,
    three_sigma_estimate,
    three_sigma_mdeg,
    wind_error_covariance,
)

U50 = 50 / 3.6
TABLE4 = {("el", "front"): (2.6, 2.2, 3.0), ("el", "side"): (0.7, 0.5, 0.9),
          ("az", "front"): (0.1, 0.05, 0.2), ("az", "side"): (2.1, 1.8, 2.4)}
AXIS = {"az": 0, "el": 1}


@pytest.fixture(scope="module")
def loop():
    return default_model().position_loop("kp1")


@pytest.fixture(scope="module")
def loads() -> WindLoads:
    return default_wind_loads()


@pytest.fixture(scope="module")
def wind_response(loop) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and the loop's Tw -> servo-error responses, (n_f, 2, 2)."""
    f = np.geomspace(1e-5, 200.0, 60000)
    return f, freqresp(loop, f, ["e_a", "e_e"], ["Tw_az", "Tw_el"])


@pytest.fixture(scope="module")
def sims(loop, loads) -> dict:
    """Two 30-min records per direction at 0.05 s (seeded)."""
    rng = np.random.default_rng(12345)
    return {d: simulate_wind_response(loop, loads, U50, d, 1800.0, 0.05, rng, n_records=2)
            for d in ("front", "side")}


# ------------------------------------------------------------------ Table 4
@pytest.mark.parametrize("axis,direction", list(TABLE4))
def test_regression_calibrated_table4_exact(loop, loads, axis: str, direction: str) -> None:
    """The calibration's objective: the exact 50 km/h figures are Table 4's (to 1 %)."""
    report, lo, hi = TABLE4[(axis, direction)]
    value = three_sigma_mdeg(loop, loads, U50, direction)[AXIS[axis]]
    assert value == pytest.approx(report, rel=0.01)
    assert lo <= value <= hi


@pytest.mark.parametrize("axis,direction", list(TABLE4))
def test_table4_time_domain_agrees_with_lyapunov(loop, loads, sims, axis: str, direction: str) -> None:
    ts, rel = three_sigma_estimate(sims[direction])
    k = AXIS[axis]
    exact = three_sigma_mdeg(loop, loads, U50, direction)[k]
    assert rel[k] < 0.03  # statistical error of two 30-min records
    assert rad_to_mdeg(ts[k]) == pytest.approx(exact, rel=max(4 * rel[k], 0.02))
    _, lo, hi = TABLE4[(axis, direction)]
    assert lo <= rad_to_mdeg(ts[k]) <= hi


def _three_sigma_by_formula(wind_response, loads, speed: float, direction: str) -> np.ndarray:
    """3 sqrt(int |H(f) g(U)|^2 S_Davenport(f; U) df), mdeg: the load model written out (gust
    torque rho U A D C u, Davenport spectrum at U) with the formula, not the shaping filter."""
    f, H = wind_response
    h = H @ loads.gust_gain(speed, direction)
    var = integrate.trapezoid(np.abs(h) ** 2 * davenport_psd(f, speed)[:, None], f, axis=0)
    return rad_to_mdeg(3 * np.sqrt(var))


@pytest.mark.parametrize("direction", ["front", "side"])
def test_lyapunov_agrees_with_psd_integral_of_the_formula(loop, loads, wind_response, direction: str) -> None:
    """int |H(f) g|^2 S_Davenport(f) df with the formula, not the rational filter."""
    by_integral = _three_sigma_by_formula(wind_response, loads, U50, direction)
    # the 4th-order filter is within 7.5 % in PSD; the variances agree much better
    assert three_sigma_mdeg(loop, loads, U50, direction) == pytest.approx(by_integral, rel=0.03)


def test_lyapunov_residual_small_on_balanced_realisation(loop, loads) -> None:
    A, G, _ = augment_with_wind(loop, loads, U50, "front")
    P = linalg.solve_continuous_lyapunov(A, -G @ G.T)
    assert np.abs(A @ P + P @ A.T + G @ G.T).max() < 1e-6 * np.abs(P).max()


def test_error_grows_with_speed(loop, loads) -> None:
    e = [three_sigma_mdeg(loop, loads, v / 3.6, "front")[1] for v in (30, 50, 70)]
    assert e[0] < e[1] < e[2]
    # gust torque ~ U * sigma_u ~ U^2, and the spectrum moves up in frequency with U
    assert 1.5 < e[2] / e[1] < 3.0


@pytest.mark.parametrize("axis,direction", [("el", "front"), ("az", "side"), ("el", "side"),
                                            ("az", "front")])
def test_wind_error_scaling_30_to_70_kmh(loop, loads, wind_response, axis: str, direction: str) -> None:
    """Not set by the calibration (which fixes 50 km/h only).  The load model gives
    3 sigma ~ U^2 sqrt(I(U)), I(U) = int |H(x U / L)|^2 g(x) dx (x = L f / U, g the normalised
    Davenport shape): U^2 from the torque rho U A D C u with sigma_u ~ U, and I(U) from the
    spectrum moving up in frequency with U.  So between 30 and 70 km/h (i) the exact figures
    scale like the formula integral (the filter's U-scaling is right), and (ii) the ratio lies
    between (70/30)^2, a frequency-flat loop, and (70/30)^3, the steepest rise |H| ~ f of a
    loop with integral action (below its bandwidth, where the gust energy is)."""
    k = AXIS[axis]
    exact = {v: three_sigma_mdeg(loop, loads, v / 3.6, direction)[k] for v in (30.0, 70.0)}
    formula = {v: _three_sigma_by_formula(wind_response, loads, v / 3.6, direction)[k] for v in (30.0, 70.0)}
    for v in (30.0, 70.0):
        assert exact[v] == pytest.approx(formula[v], rel=0.03), v
    ratio = exact[70.0] / exact[30.0]
    assert ratio == pytest.approx(formula[70.0] / formula[30.0], rel=0.02)
    assert (70 / 30) ** 2 < ratio < (70 / 30) ** 3


def test_simulation_reproducible(loop, loads) -> None:
    a = simulate_wind_response(loop, loads, U50, "side", 20.0, 0.05, np.random.default_rng(3))
    b = simulate_wind_response(loop, loads, U50, "side", 20.0, 0.05, np.random.default_rng(3))
    c = simulate_wind_response(loop, loads, U50, "side", 20.0, 0.05, np.random.default_rng(4))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_simulation_needs_generator(loop, loads) -> None:
    with pytest.raises(TypeError, match="Generator"):
        simulate_wind_response(loop, loads, U50, "side", 20.0, 0.05, 3)


# ------------------------------------------------------------------ loads and units
def test_coefficients_by_direction(loads) -> None:
    assert np.allclose(loads.coefficients("front"), loads.c_front)
    assert np.allclose(loads.coefficients("side"), loads.c_side)
    th = math.radians(30)
    assert np.allclose(loads.coefficients(th), loads.c_front * math.cos(th) + loads.c_side * math.sin(th))


def test_mean_torque_scales_with_u_squared_and_gust_with_u(loads) -> None:
    assert np.allclose(loads.mean_torque(2 * U50, "front"), 4 * loads.mean_torque(U50, "front"))
    assert np.allclose(loads.gust_gain(2 * U50, "side"), 2 * loads.gust_gain(U50, "side"))


def test_torque_units_by_hand(loads) -> None:
    """T_mean = 1/2 rho U^2 (pi D^2/4) D C with rho 1.1 kg/m^3, D 70 m (configs/wind.yaml)."""
    C = loads.coefficients("front")
    q = 0.5 * 1.1 * U50 ** 2
    assert np.allclose(loads.mean_torque(U50, "front"), q * math.pi * 35.0 ** 2 * 70.0 * C)
    # gust torque sigma ~ rho U A D C sigma_u, sigma_u^2 = 6 kappa U^2 (Davenport variance)
    sd_u = math.sqrt(filter_variance(loads.gust_filter(U50)))
    assert sd_u == pytest.approx(math.sqrt(6 * 0.005) * U50, rel=0.03)


def test_gust_torque_order_of_magnitude(loads) -> None:
    """Moment coefficients of order 0.03-0.15 would give 0.3-1.4 MN*m gust rms at 50 km/h;
    the model needs a few times less (docs/wind.md section 5 says why); check the order, not
    the calibration's exact value."""
    sd_u = math.sqrt(6 * 0.005) * U50
    el_front = abs(loads.gust_gain(U50, "front")[1]) * sd_u
    az_side = abs(loads.gust_gain(U50, "side")[0]) * sd_u
    assert 3e4 < el_front < 3e6 and 1e4 < az_side < 3e6
    assert el_front > 10 * abs(loads.gust_gain(U50, "front")[0]) * sd_u  # front wind: el dominates


@pytest.mark.parametrize("bad", ["back", "", "FRONT"])
def test_unknown_direction(bad: str) -> None:
    with pytest.raises(ValueError, match="direction"):
        direction_angle(bad)


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_nonfinite_direction(bad: float) -> None:
    with pytest.raises(ValueError, match="finite"):
        direction_angle(bad)


@pytest.mark.parametrize("speed", [0.0, -3.0, float("nan")])
def test_bad_speed(loads, speed: float) -> None:
    with pytest.raises(ValueError, match="wind speed"):
        loads.mean_torque(speed, "front")


def test_covariance_rejects_unknown_output(loop, loads) -> None:
    with pytest.raises(KeyError, match="nope"):
        wind_error_covariance(loop, loads, U50, "front", ["nope"])


# ------------------------------------------------------------------ config
def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "wind.yaml"
    p.write_text(text)
    return p


def _shipped() -> str:
    return Path(load_wind_config().path).read_text()


@pytest.mark.parametrize("old,new,match", [
    ("value: 1.1,", "value: -1.1,", "loads.air_density"),
    ("value: 2.6,", "value: 3.6,", "table4.el_front"),
    ('unit: "kg/m^3"', 'unit: "m"', "loads.air_density"),
    ("value: 4,", "value: 7,", "filter_order"),
])
def test_config_errors_name_field_and_file(tmp_path: Path, old: str, new: str, match: str) -> None:
    text = _shipped()
    assert old in text
    p = _write(tmp_path, text.replace(old, new, 1))
    with pytest.raises(ConfigError, match=match) as exc:
        load_wind_config(p)
    assert str(p) in str(exc.value)


def test_config_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_wind_config(tmp_path / "none.yaml")


def test_config_si(tmp_path: Path) -> None:
    c = load_wind_config()
    assert c.table4.speed == pytest.approx(50 / 3.6)
    assert c.table4.el_front == pytest.approx(math.radians(2.6e-3))


# ------------------------------------------------------------------ discretisation helpers
def _random_stable(n: int, m: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n)
    return A, rng.standard_normal((n, m))


def test_discretize_matches_scipy_zoh() -> None:
    A, B = _random_stable(5, 2, 0)
    Ad, Bd, Qd = discretize(A, B, 0.1)
    ref = signal.cont2discrete((A, B, np.eye(5), np.zeros((5, 2))), 0.1, method="zoh")
    assert Qd is None
    assert np.allclose(Ad, ref[0], atol=1e-12) and np.allclose(Bd, ref[1], atol=1e-12)


def test_discretize_noise_is_step_size_independent() -> None:
    """Two half steps give the same mean map and noise covariance as one full step."""
    A, G = _random_stable(4, 1, 1)
    Ad1, _, Q1 = discretize(A, G, 0.2, G)
    Adh, _, Qh = discretize(A, G, 0.1, G)
    assert np.allclose(Adh @ Adh, Ad1, atol=1e-12)
    assert np.allclose(Adh @ Qh @ Adh.T + Qh, Q1, atol=1e-12)


def test_discretize_noise_by_quadrature() -> None:
    A, G = _random_stable(3, 2, 2)
    _, _, Qd = discretize(A, np.zeros((3, 1)), 0.3, G)
    Q = integrate.quad_vec(lambda s: linalg.expm(A * s) @ G @ G.T @ linalg.expm(A.T * s), 0, 0.3)[0]
    assert np.allclose(Qd, Q, atol=1e-10)


@pytest.mark.parametrize("dt", [0.0, -0.1, float("nan")])
def test_discretize_bad_dt(dt: float) -> None:
    with pytest.raises(ValueError, match="dt"):
        discretize(np.eye(2), np.ones((2, 1)), dt)


def test_noise_factor_and_balance() -> None:
    Q = np.array([[2.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    L = noise_factor(Q)
    assert np.allclose(L @ L.T, Q)
    A, B = _random_stable(4, 1, 3)
    S = np.diag([1e6, 1.0, 1e-3, 10.0])
    As, Bs, Cs = S @ A @ np.linalg.inv(S), S @ B, np.ones((1, 4)) @ np.linalg.inv(S)
    Ab, Bb, Cb, s = balance(As, Bs, Cs)
    f = [0.0, 0.1, 1.0]
    for w in f:
        h1 = Cs @ np.linalg.solve(1j * w * np.eye(4) - As, Bs)
        h2 = Cb @ np.linalg.solve(1j * w * np.eye(4) - Ab, Bb)
        assert np.allclose(h1, h2)
    assert np.abs(Ab).max() < np.abs(As).max()
