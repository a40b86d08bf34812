"""Tests of the monopulse sensor (:mod:`dss14_env.envs.monopulse`) in both environments."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from scipy import stats

from dss14_env.envs.config import load_env_config
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.monopulse import (
    MonopulseConstants,
    half_power_beamwidth_mdeg,
    jitter_mdeg,
    sensor_constants,
    sensor_reset,
    sensor_step,
)
from dss14_env.envs.vector import DSS14VectorEnv

MONO = ["encoders", "monopulse"]


def _run(env: DSS14Env, steps: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observations, true pointing errors and measured ones (info), ``[el, xel]`` mdeg, of a hold
    with the actions at zero.
    """
    obs, info = env.reset(seed=seed)
    o, p, m = [obs], [], []
    keys = ("pointing_error_el_mdeg", "pointing_error_xel_mdeg")
    p.append([info[k] for k in keys])
    m.append([info["monopulse_el_mdeg"], info["monopulse_xel_mdeg"]])
    for _ in range(steps):
        obs, _, term, _, info = env.step(np.zeros(2))
        assert not term
        o.append(obs)
        p.append([info[k] for k in keys])
        m.append([info["monopulse_el_mdeg"], info["monopulse_xel_mdeg"]])
    return np.array(o), np.array(p), np.array(m)


def test_jitter_follows_the_tracking_error_formula() -> None:
    # sigma = theta_3dB / (k_m sqrt(2 C/N0 / B_L)): 10 dB more C/N0 divides it by sqrt(10)
    s30, s40 = (jitter_mdeg(c, 1.0, "Ka", 1.6, 0.02) for c in (30.0, 40.0))
    assert s30 / s40 == pytest.approx(math.sqrt(10.0), rel=1e-12)
    assert jitter_mdeg(30.0, 4.0, "Ka", 1.6, 0.02) == pytest.approx(2.0 * s30, rel=1e-12)
    assert s30 == pytest.approx(half_power_beamwidth_mdeg("Ka") / (1.6 * math.sqrt(2000.0)), rel=1e-12)
    assert jitter_mdeg(None, 1.0, "Ka", 1.6, 0.02) == 0.0
    # the Gaussian beam's 0.1-dB width is 2 sqrt(0.1 / 12) of its half-power width
    assert half_power_beamwidth_mdeg("X") * 2.0 * math.sqrt(0.1 / 12.0) == pytest.approx(5.9, rel=1e-12)


@pytest.mark.parametrize("update_s", [None, 0.06])
def test_loop_output_noise_has_the_specified_std_and_correlation(update_s: float | None) -> None:
    # the sensor alone on a zero true error: a stationary start, then the loop; over many
    # independent rows the output's variance at every step is sigma^2 (chi-square CI) and the
    # correlation between updates is the loop's pole a (Fisher-z CI)
    k = MonopulseConstants.from_config(load_env_config(sensors=MONO, monopulse_update_s=update_s,
                                                       monopulse_cnr_dbhz=25.0))
    rng = np.random.default_rng(7)
    n, steps = 4000, 30 * k.n_update
    zero = np.zeros((n, 2))
    st = sensor_reset(zero, rng.standard_normal((n, 2)), k)
    outs, mc, obs = [st.out.copy()], sensor_constants(k), np.empty((n, 14), np.float32)
    for _ in range(steps):
        sensor_step(st.history, st.out, st.k, zero.T.copy(), rng.standard_normal((1, n, 2)), 0, mc, 0.1, obs)
        outs.append(st.out.copy())
    x = np.array(outs)[::k.n_update]  # one sample per update (held in between)
    dof = n * 2
    lo, hi = (stats.chi2.ppf(q, dof) / dof for q in (0.0005, 0.9995))  # 99.9 % for each of 31 steps x 2
    var = (x ** 2).mean(axis=(1, 2))
    assert np.all((lo * k.sigma ** 2 <= var) & (var <= hi * k.sigma ** 2)), var / k.sigma ** 2
    r = np.corrcoef(x[10].ravel(), x[11].ravel())[0, 1]
    half = 3.3 / math.sqrt(dof - 3)
    assert math.tanh(math.atanh(k.a) - half) <= r <= math.tanh(math.atanh(k.a) + half)
    if update_s:  # held between updates
        y = np.array(outs)
        assert np.array_equal(y[1], y[0]) and np.array_equal(y[2], y[0]) and not np.array_equal(y[3], y[0])


def test_without_loop_filter_the_env_measurement_is_the_true_error_plus_white_noise() -> None:
    # no loop filter, no latency: measured - true is white with the specified std
    env = DSS14Env(sensors=MONO, scenario="hold", monopulse_bandwidth_hz=None, monopulse_cnr_dbhz=40.0)
    _, p, m = _run(env, 1500)
    d = (m - p).ravel()
    sigma = env.monopulse.sigma
    dof = d.size
    lo, hi = (stats.chi2.ppf(q, dof) / dof for q in (0.001, 0.999))
    assert lo * sigma ** 2 <= np.mean(d ** 2) <= hi * sigma ** 2
    assert abs(np.corrcoef(d[:-2:2], d[2::2])[0, 1]) < 3.3 / math.sqrt(dof / 2)  # el: step to step


def test_zero_noise_reduces_to_the_true_pointing_error() -> None:
    env = DSS14Env(sensors=MONO, scenario="track", monopulse_cnr_dbhz=None, monopulse_bandwidth_hz=None)
    o, p, m = _run(env, 300)
    assert np.array_equal(m, p)
    np.testing.assert_array_equal(o[:, 12:14], (p / env.config.error_scale_mdeg).astype(np.float32))


def test_latency_delays_the_true_error_by_whole_steps() -> None:
    env = DSS14Env(sensors=MONO, scenario="track", monopulse_cnr_dbhz=None, monopulse_bandwidth_hz=None,
                   monopulse_latency_s=0.1)
    _, p, m = _run(env, 100)
    assert np.array_equal(m[5:], p[:-5])
    assert np.array_equal(m[:5], np.repeat(p[:1], 5, axis=0))


def test_sensor_off_keeps_the_observation_and_draws() -> None:
    # the default (encoders only) and the monopulse env share everything but the sensor's draws
    off, on = DSS14Env(scenario="hold"), DSS14Env(scenario="hold", sensors=MONO)
    assert off.observation_space.shape == (12,) and on.observation_space.shape == (14,)
    o_off, i_off = off.reset(seed=5)
    o_on, i_on = on.reset(seed=5)
    assert "monopulse_el_mdeg" not in i_off
    np.testing.assert_array_equal(o_off, o_on[:12])  # the episode is drawn before the sensor's start
    assert on.observation_space.contains(o_on)


def test_single_and_vector_envs_agree_on_the_monopulse_observation() -> None:
    kw = dict(sensors=MONO, scenario="hold", monopulse_latency_s=0.04, monopulse_update_s=0.04)
    single = DSS14Env(**kw)
    o, _, _ = _run(single, 300, seed=9)
    venv = DSS14VectorEnv(num_envs=2, **kw)
    vo = [venv.reset(seed=9)[0][0]]
    for _ in range(300):
        vo.append(venv.step(np.zeros((2, 2)))[0][0])
    np.testing.assert_allclose(np.array(vo)[:, 12:], o[:, 12:], rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize(("kw", "match"), [
    (dict(sensors=["monopulse"]), "field 'sensors': must list 'encoders' first"),
    (dict(sensors=["encoders", "monopulse", "monopulse"]), "field 'sensors': must list 'encoders' first"),
    (dict(sensors=["encoders", "radar"]), "field 'sensors': must be one of"),
    (dict(sensors="monopulse"), "field 'sensors': must be a list"),
    (dict(monopulse_band="K"), "field 'monopulse_band'"),
    (dict(monopulse_cnr_dbhz=-3.0), "field 'monopulse_cnr_dbhz'"),
    (dict(monopulse_bandwidth_hz=0.0), "field 'monopulse_bandwidth_hz'"),
    (dict(monopulse_bandwidth_hz=30.0), "field 'monopulse_bandwidth_hz': must be <= the update rate"),
    (dict(monopulse_update_s=0.03), "field 'monopulse_update_s': must be null or a whole multiple of dt"),
    (dict(monopulse_latency_s=0.01), "field 'monopulse_latency_s': must be a whole multiple"),
    (dict(monopulse_slope=float("nan")), "field 'monopulse_slope'"),
])
def test_bad_sensor_options_are_refused_with_one_line(kw: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match) as err:
        DSS14Env(**{"sensors": MONO, **kw})
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("vector", [False, True])
def test_snapshots_and_copies_continue_the_sensor_bit_for_bit(vector: bool) -> None:
    kw = dict(sensors=MONO, scenario="hold", monopulse_latency_s=0.04)
    env = DSS14VectorEnv(num_envs=2, **kw) if vector else DSS14Env(**kw)
    act = np.zeros((2, 2)) if vector else np.zeros(2)
    env.reset(seed=4)
    for _ in range(300):  # into the second noise block
        env.step(act)
    snap, twin = env.get_state(), copy.deepcopy(env)
    a = [env.step(act)[0] for _ in range(260)]
    env.set_state(snap)
    b = [env.step(act)[0] for _ in range(260)]
    c = [twin.step(act)[0] for _ in range(260)]
    assert np.array_equal(np.array(a), np.array(b)) and np.array_equal(np.array(a), np.array(c))


def _sense(p: np.ndarray, **kw: object) -> tuple[np.ndarray, np.ndarray, MonopulseConstants]:
    """The sensor's outputs ``(T, 2)`` and observation entries ``(T, 2)`` for the true pointing
    errors ``p`` ``(T, 2)`` (mdeg; ``p[0]`` at the reset), with zero noise normals.
    """
    k = MonopulseConstants.from_config(load_env_config(sensors=MONO, **kw))
    st = sensor_reset(p[:1], np.zeros((1, 2)), k)
    outs, obs = [st.out[0].copy()], np.zeros((1, 14), np.float32)
    o = [obs[0, 12:].copy()]
    for pk in p[1:]:
        sensor_step(st.history, st.out, st.k, pk[:, None].copy(), np.zeros((1, 1, 2)), 0, sensor_constants(k),
                    0.1, obs)
        outs.append(st.out[0].copy())
        o.append(obs[0, 12:].copy())
    return np.array(outs), np.array(o), k


def test_noiseless_sensor_without_loop_is_the_error_late_by_its_latency_and_held_between_updates() -> None:
    # f[k] = p[k - d] (the delay line starts full of p[0]), updated every n_u steps, held between
    p = np.random.default_rng(3).normal(size=(40, 2)) * 5.0
    f, _, k = _sense(p, monopulse_cnr_dbhz=None, monopulse_bandwidth_hz=None, monopulse_latency_s=0.04,
                     monopulse_update_s=0.06)
    assert (k.n_delay, k.n_update, k.a, k.sigma) == (2, 3, 0.0, 0.0)
    for step in range(1, 40):
        last_update = step - step % 3
        want = p[0] if last_update == 0 else p[max(last_update - 2, 0)]
        assert np.array_equal(f[step], want), step


def test_noiseless_loop_is_a_first_order_filter_of_pole_exp_minus_4_bl_t() -> None:
    p = np.random.default_rng(4).normal(size=(30, 2))
    f, _, k = _sense(p, monopulse_cnr_dbhz=None, monopulse_bandwidth_hz=2.0)
    a = math.exp(-4.0 * 2.0 * 0.02)
    assert k.a == pytest.approx(a, rel=1e-15)
    want = [p[0]]
    for pk in p[1:]:
        want.append(a * want[-1] + (1.0 - a) * pk)
    np.testing.assert_allclose(f, np.array(want), rtol=1e-13, atol=1e-15)


def test_sensor_observation_is_the_measurement_in_error_scale_units_clamped_to_1e4() -> None:
    p = np.array([[0.0, 0.0], [3.0, -4.0], [2.0e5, -3.0e5], [-1.0e6, 99_990.0]])
    _, o, _ = _sense(p, monopulse_cnr_dbhz=None, monopulse_bandwidth_hz=None)
    assert o.dtype == np.float32
    assert o[1].tolist() == [pytest.approx(0.3), pytest.approx(-0.4)]
    assert o[2].tolist() == [1.0e4, -1.0e4] and o[3].tolist() == [-1.0e4, 9999.0]
