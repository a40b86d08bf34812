"""The step's rules (:mod:`dss14_env.envs.fused`), each against its definition: limiter edges,
encoder quantisation, termination boundaries, the reward formula, the observation layout and
clamping, the info keys; the same source run as Python (``NUMBA_DISABLE_JIT=1``) gives the same
bits; a non-finite plant output is refused.  Expected values are worked out from the documented
formulas (docs/env.md, the module docstring), not taken from the code.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from dss14_env.core.units import R2D, R2MD
from dss14_env.envs import fused
from dss14_env.envs.core import INFO_KEYS, OBS, OBS_ERROR_BOUND, OBS_ERROR_RATE_BOUND, StepConstants
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.vector import DSS14VectorEnv

Q = 2.0 ** -20  # an encoder count (rad) of exact inverse, so that half counts are exact


def _k(**kw) -> StepConstants:
    base = dict(dt=0.02, action_scale=0.01, rate_limit=0.005, rate_step=0.001, rate_clip=True, quantum=0.0,
                encoder_sigma=0.0, error_scale=10.0, action_change_weight=1.0, termination_penalty=1e4,
                el_limits=(0.1, 1.5), az_centre=0.0, az_half_range=4.6)
    return StepConstants(**{**base, **kw})


def _limit(a: list, r_prev: list, k: StepConstants) -> tuple:
    A, out = np.array([a], float), np.full((1, 2), -7.0)
    r, hit = np.full((1, 2), -7.0), np.zeros((2, 1))
    bad = fused.limit_commands(A, np.array([r_prev], float), fused.constants(k, 1.0), out, r, hit)
    return bad, out[0].tolist(), r[0].tolist(), bool(hit[0, 0]), bool(hit[1, 0])


@pytest.mark.parametrize("a, r_prev, r, rate_hit, acc_hit", [
    ([2.0, -3.0], [0.0, 0.0], [0.001, -0.001], True, True),     # box clip, rate clip, acceleration
    ([0.4, 0.0], [0.0035, 0.0], [0.004, 0.0], False, False),   # within one rate step: no hit
    ([0.5, 0.0], [0.004, 0.0], [0.005, 0.0], False, False),    # exactly the rate limit: no hit
    ([0.5000001, 0.0], [0.0049, 0.0], [0.005, 0.0], True, False),  # just beyond it: clipped
    ([0.0, -0.3], [0.0, 0.0], [0.0, -0.001], False, True),     # acceleration limit, negative
])
def test_limiter_edges(a, r_prev, r, rate_hit, acc_hit) -> None:
    bad, clipped, got, rh, ah = _limit(a, r_prev, _k())
    assert bad == -1
    assert clipped == [min(max(x, -1.0), 1.0) for x in a]
    np.testing.assert_allclose(got, r, rtol=1e-12, atol=1e-18)
    assert (rh, ah) == (rate_hit, acc_hit)


def test_without_rate_clip_the_rate_limit_is_never_flagged() -> None:
    # action_scale <= rate_limit: the clip cannot act (rate_clip False), only the acceleration limit
    bad, _, got, rh, ah = _limit([1.0, -1.0], [0.01, -0.01], _k(action_scale=0.01, rate_limit=0.01,
                                                               rate_clip=False))
    assert (bad, got, rh, ah) == (-1, [0.01, -0.01], False, False)


@pytest.mark.parametrize("a, row", [([[0.0, 0.0], [math.nan, 0.0]], 1), ([[0.0, math.inf], [0.0, 0.0]], 0)])
def test_limiter_refuses_a_non_finite_action_before_writing(a: list, row: int) -> None:
    A, out, r = np.array(a), np.full((2, 2), -7.0), np.full((2, 2), -7.0)
    kc, hit = fused.constants(_k(), 1.0), np.zeros((2, 2))
    assert fused.limit_commands(A, np.zeros((2, 2)), kc, out, r, hit) == row
    assert (out == -7.0).all() and (r == -7.0).all()


def _after(k: StepConstants, theta=(0.0, 0.0), point=(0.0, 0.0), c=(0.0, 0.0), cd=(0.0, 0.0),
           start=(0.0, 0.5), me=1e3, a=(0.0, 0.0), a_prev=(0.0, 0.0), em_prev=(0.0, 0.0), r=(0.0, 0.0),
           noise=(0.0, 0.0), xel=0.7, clamp_always=False, hits=(0, 0), rate_hit=False, acc_hit=False) -> dict:
    """One sub-environment through :func:`fused.after_product`; its results by name."""
    Y = np.array([[theta[0], theta[1], point[0], point[1]]])
    ep = fused.episode_rows(np.array([start]), np.array([me]), np.array([[3.0, 0.25]]))
    obs, em, out = fused.step_outputs(1)
    h = np.array([hits], float)
    flags = fused.after_product(Y, 0, np.zeros(1, np.int64), np.array([[c]]), np.array([[cd]]),
                                np.array([[noise]]), 0, ep, np.array([a]), np.array([a_prev]),
                                np.array([em_prev]), np.array([r]), np.array([[rate_hit], [acc_hit]], float),
                                h, fused.constants(k, xel), clamp_always, obs, em, out)
    v = out[:, 0].tolist()
    info = dict(zip(fused.INFO_FLOAT_ROWS + fused.INFO_INT_ROWS, v[:10] + v[12:], strict=True))
    return dict(obs=obs[0], rew=v[fused.REWARD_ROW], term=v[fused.TERMINATED_ROW] == 1.0, em=em[0].tolist(),
                info=info, flags=flags, hits=h[0].tolist())


@pytest.mark.parametrize("counts, read", [(0.5, 1.0), (-0.5, 0.0), (1.49, 1.0), (-1.51, -2.0), (10.6, 11.0)])
def test_encoders_round_the_absolute_angle_to_the_nearest_count_half_up(counts: float, read: float) -> None:
    # the start lies on 10.25 counts: a reading is absolute, so its phase counts
    start = 10.25 * Q
    theta = counts * Q - start
    res = _after(_k(quantum=Q), theta=(theta, 0.0), start=(start, 0.5))
    rel = read * Q - start
    assert res["obs"][OBS.encoder][0] == np.float32(rel * R2D)
    assert res["em"][0] == pytest.approx(-rel * R2MD, rel=1e-9)  # c = 0: e_meas = -reading
    assert res["info"]["servo_error_az_mdeg"] == pytest.approx(-theta * R2MD, rel=1e-12)  # true error


def test_exact_encoders_read_the_angle_and_noise_adds_before_the_rounding() -> None:
    res = _after(_k(), theta=(1.234e-4, -5e-5))
    assert res["em"] == pytest.approx([-1.234e-4 * R2MD, 5e-5 * R2MD], rel=1e-9)
    # noise of 0.3 counts on a reading 0.3 counts above a count: rounds up only with the noise
    start = 7.0 * Q
    quiet = _after(_k(quantum=Q, encoder_sigma=1e-6), theta=(0.3 * Q, 0.0), start=(start, 0.5))
    noisy = _after(_k(quantum=Q, encoder_sigma=1e-6), theta=(0.3 * Q, 0.0), start=(start, 0.5),
                   noise=(0.3 * Q, 0.0))
    assert quiet["obs"][OBS.encoder][0] == 0.0 and noisy["obs"][OBS.encoder][0] == np.float32(Q * R2D)


def test_termination_is_strictly_beyond_each_bound() -> None:
    k, theta = _k(), -1e-3
    e = (0.0 - theta) * R2MD  # the servo error of this angle (command 0), mdeg
    assert _after(k, theta=(theta, 0.0), me=e)["term"] is False
    assert _after(k, theta=(theta, 0.0), me=math.nextafter(e, 0.0))["term"] is True
    assert _after(k, theta=(0.0, theta), me=math.nextafter(e, 0.0))["term"] is True
    # elevation at the travel limits: on them is inside, a step beyond is out
    lo, hi = k.el_limits
    assert _after(k, start=(0.0, lo))["term"] is False and _after(k, start=(0.0, hi))["term"] is False
    assert _after(k, start=(0.0, math.nextafter(lo, 0.0)))["term"] is True
    assert _after(k, start=(0.0, math.nextafter(hi, 2.0)))["term"] is True
    # azimuth beyond the half range about the wrap centre
    assert _after(k, start=(k.az_half_range, 0.5))["term"] is False
    assert _after(k, start=(math.nextafter(k.az_half_range, 9.0), 0.5))["term"] is True
    assert _after(_k(az_centre=1.0), start=(1.0 - k.az_half_range, 0.5))["term"] is False


@pytest.mark.parametrize("pointing", [False, True])
def test_reward_is_minus_the_quadratic_cost_less_the_penalty_on_termination(pointing: bool) -> None:
    k = _k(error_scale=4.0, action_change_weight=0.5, termination_penalty=1e4, pointing_reward=pointing)
    theta, point, c, xel = (2e-5, -3e-5), (1e-5, 4e-5), (1e-4, -2e-4), 0.6
    a, a_prev = (0.3, -0.2), (0.1, 0.4)
    e = [(c[0] - theta[0]) * R2MD, (c[1] - theta[1]) * R2MD]
    p = [(c[1] - point[0]) * R2MD, (c[0] * xel - point[1]) * R2MD]
    s = p if pointing else e
    want = -((s[0] ** 2 + s[1] ** 2) / 16.0 + 0.5 * ((0.2) ** 2 + (-0.6) ** 2))
    res = _after(k, theta=theta, point=point, c=c, a=a, a_prev=a_prev, xel=xel)
    assert res["rew"] == pytest.approx(want, rel=1e-12) and not res["term"]
    assert [res["info"]["pointing_error_el_mdeg"], res["info"]["pointing_error_xel_mdeg"]] == pytest.approx(p)
    ended = _after(k, theta=theta, point=point, c=c, a=a, a_prev=a_prev, xel=xel, me=1.0)
    assert ended["term"] and ended["rew"] == pytest.approx(want - 1e4, rel=1e-12)


def test_observation_layout_and_units() -> None:
    k = _k(error_scale=10.0, dt=0.02, rate_limit=0.005)
    res = _after(k, theta=(-3e-5, 2e-5), c=(1e-3, -2e-3), cd=(0.002, -0.001), em_prev=(1.0, -2.0),
                 r=(0.004, -0.0025))
    em = [(1e-3 + 3e-5) * R2MD, (-2e-3 - 2e-5) * R2MD]
    want = {"error": [em[0] / 10.0, em[1] / 10.0],
            "error_rate": [(em[0] - 1.0) / (10.0 * 0.02), (em[1] + 2.0) / (10.0 * 0.02)],
            "command": [1e-3 * R2D, -2e-3 * R2D], "command_rate": [0.4, -0.2],
            "encoder": [-3e-5 * R2D, 2e-5 * R2D], "prev_rate": [0.8, -0.5]}
    assert res["obs"].dtype == np.float32 and res["obs"].shape == (12,)
    for name, v in want.items():
        np.testing.assert_allclose(res["obs"][getattr(OBS, name)], v, rtol=2e-7, err_msg=name)


def test_observation_clamps_errors_only_on_termination_or_when_always_asked() -> None:
    k = _k()
    big = dict(c=(0.04, -0.04), me=1e9)  # errors of 2.3e3 mdeg = 2.3e2 units; rates 1.1e4 units/s
    free = _after(k, **big)
    assert free["obs"][0] == np.float32(0.04 * R2MD / 10.0)
    huge = dict(c=(2.0, -2.0), em_prev=(-1e6, 1e6))  # beyond both bounds
    assert abs(_after(k, **huge, me=1e9)["obs"][0]) > OBS_ERROR_BOUND
    for kw in (dict(me=1.0), dict(me=1e9, clamp_always=True)):
        o = _after(k, **huge, **kw)["obs"]
        bounds = [OBS_ERROR_BOUND, -OBS_ERROR_BOUND, OBS_ERROR_RATE_BOUND, -OBS_ERROR_RATE_BOUND]
        assert o[:4].tolist() == bounds


def test_info_values_and_hit_counts() -> None:
    res = _after(_k(), r=(0.002, -0.001), hits=(3, 5), rate_hit=True, acc_hit=False)
    info = res["info"]
    assert (info["wind_speed_mps"], info["wind_direction_rad"]) == (3.0, 0.25)
    assert info["rate_command_az_deg_s"] == pytest.approx(0.002 * R2D)
    assert res["hits"] == [4, 5] and (info["n_rate_limited"], info["n_accel_limited"]) == (4, 5)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
@pytest.mark.parametrize("quantum", [0.0, Q])
def test_a_non_finite_plant_output_is_flagged_and_counts_nothing(bad: float, quantum: float) -> None:
    res = _after(_k(quantum=quantum), theta=(bad, 0.0), hits=(2, 2), rate_hit=True)
    assert res["flags"] & fused.NON_FINITE and res["hits"] == [2, 2]


def test_single_env_step_info_keys_and_types() -> None:
    env = DSS14Env()
    env.reset(seed=0)
    obs, rew, term, trunc, info = env.step(np.array([0.3, -2.0], np.float32))
    assert list(info) == list(INFO_KEYS) and obs.shape == (12,) and obs.dtype == np.float32
    assert type(rew) is float and type(term) is bool and trunc is False
    assert all(type(info[key]) is float for key in fused.INFO_FLOAT_ROWS)
    assert all(type(info[key]) is int for key in fused.INFO_INT_ROWS)
    assert type(info["rate_limited"]) is bool and type(info["accel_limited"]) is bool
    assert info["action_unclipped"] == (pytest.approx(0.3), -2.0) and info["accel_limited"] is True
    venv = DSS14VectorEnv(num_envs=3)
    venv.reset(seed=0)
    *_, vinfo = venv.step(np.zeros((3, 2)))
    assert list(vinfo) == list(INFO_KEYS) and all(np.shape(v)[0] == 3 for v in vinfo.values())


def test_a_deep_copy_of_the_step_info_is_equal_and_shares_nothing_mutable() -> None:
    """``copy.deepcopy`` of a step's info (what stable-baselines3's DummyVecEnv does every step):
    an equal dict of the same keys and types; values a wrapper added (an array, a nested dict)
    are copies, so changing the original afterwards leaves the copy as it was."""
    import copy

    env = DSS14Env()
    env.reset(seed=0)
    *_, info = env.step(np.array([0.3, -2.0], np.float32))
    info["terminal_observation"] = obs = np.arange(3.0)
    info["episode"] = {"r": [1.0]}
    c = copy.deepcopy(info)
    assert c == {k: v for k, v in info.items() if k not in ("terminal_observation", "episode")} | {
        "terminal_observation": c["terminal_observation"], "episode": {"r": [1.0]}}
    assert [type(v) for v in c.values()] == [type(v) for v in info.values()]
    obs[0] = 99.0
    info["episode"]["r"].append(2.0)
    info["servo_error_az_mdeg"] = -1.0
    assert c["terminal_observation"].tolist() == [0.0, 1.0, 2.0] and c["episode"] == {"r": [1.0]}
    assert c["servo_error_az_mdeg"] != -1.0


_ROLLOUT = """
import json, sys
import numpy as np
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.vector import DSS14VectorEnv
kw = dict(sensors=["encoders", "monopulse"], encoder_noise_mdeg=0.2, max_error_deg=0.002,
          monopulse_latency_s=0.02)
rng = np.random.default_rng(1)
env, venv = DSS14Env(**kw), DSS14VectorEnv(num_envs=3, max_episode_steps=40, **kw)
out = [env.reset(seed=2)[0].tolist(), venv.reset(seed=3)[0].tolist()]
for _ in range(60):
    o, r, t, _, i = env.step(rng.uniform(-2, 2, 2))
    out.append([o.tolist(), r, t, i["measured_error_az_mdeg"], i["monopulse_xel_mdeg"]])
    if t:
        out.append(env.reset()[0].tolist())
    o, r, t, _, i = venv.step(rng.uniform(-2, 2, (3, 2)))
    out.append([o.tolist(), r.tolist(), t.tolist(), i["pointing_error_el_mdeg"].tolist()])
print(json.dumps(out))
"""


def _rollout(disable_jit: bool) -> list:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1" if disable_jit else "0"}
    res = subprocess.run([sys.executable, "-c", _ROLLOUT], capture_output=True, text=True, env=env,
                         timeout=300, check=True)
    return json.loads(res.stdout)


@pytest.mark.slow
def test_the_same_source_run_as_python_gives_the_same_bits() -> None:
    # NUMBA_DISABLE_JIT=1 runs the loops as plain Python: same operations, same results
    compiled, python = _rollout(False), _rollout(True)
    assert compiled == python
    assert any(isinstance(x, list) and len(x) == 5 and x[2] for x in compiled)  # an episode ended
