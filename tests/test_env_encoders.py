"""The ``encoders`` key: drive encoders (the report's computer mode) or axis encoders that read
the structure's pointing angles ([R]'s "encoders located close to the axes").
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.core.schema import ConfigError
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.presets import PRESETS, WRAPPED_IDS
from dss14_env.envs.vector import DSS14VectorEnv

KW = dict(scenario="hold", wind_speed_kmh=50.0, wind_direction="random", wind_direction_grid_deg=[0.0, 90.0])
INFO = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg", "measured_error_el_mdeg",
        "pointing_error_el_mdeg", "pointing_error_xel_mdeg")
COS_E = math.cos(math.radians(45.0))  # the shipped structure model's elevation


def _roll(env, acts: np.ndarray) -> tuple[list, list, list]:
    obs, rew, info = [], [], []
    for a in acts:
        o, r, _, _, i = env.step(a)
        obs.append(o), rew.append(r), info.append([i[k] for k in INFO])
    return obs, rew, info


def test_axis_encoders_single_env_equals_the_vector_env() -> None:
    N, T = 3, 300
    acts = np.random.default_rng(0).uniform(-0.02, 0.02, (T, N, 2))
    venv = DSS14VectorEnv(num_envs=N, encoders="axis", **KW)
    venv.reset(seed=11)
    v_obs, v_rew, v_info = _roll(venv, acts)
    v_info = np.array(v_info)  # (T, keys, N)
    for i in range(N):
        env = DSS14Env(encoders="axis", **KW)
        env.reset(seed=11 + i)
        s_obs, s_rew, s_info = _roll(env, acts[:, i])
        np.testing.assert_allclose(np.array(s_obs), np.array(v_obs)[:, i], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(np.array(s_rew), np.array(v_rew)[:, i], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(np.array(s_info), v_info[:, :, i], rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("direction", ["front", "side"])
def test_axis_encoders_read_the_pointing_angles(direction: str) -> None:
    # exact readings: the el servo error is the el pointing error, the az servo error times
    # cos(E) the xel pointing error; with drive encoders the structure's deflection separates them
    errs = {}
    for enc in ("axis", "drive"):
        env = DSS14Env(encoders=enc, encoder_bits=None, **{**KW, "wind_direction": direction})
        env.reset(seed=2)
        e, p = [], []
        for a in np.random.default_rng(3).uniform(-0.02, 0.02, (400, 2)):
            _, _, _, _, info = env.step(a)
            e.append((info["servo_error_az_mdeg"] * COS_E, info["servo_error_el_mdeg"]))
            p.append((info["pointing_error_xel_mdeg"], info["pointing_error_el_mdeg"]))
        errs[enc] = np.array(e), np.array(p)
    e, p = errs["axis"]
    np.testing.assert_allclose(e, p, rtol=1e-9, atol=1e-9)
    e, p = errs["drive"]
    loaded = 1 if direction == "front" else 0  # el in front wind, az in side wind
    assert np.max(np.abs(e[:, loaded] - p[:, loaded])) > 0.1  # mdeg: the deflection above the drive


def test_axis_encoders_start_at_zero_error() -> None:
    # the steady-motion start holds the chosen encoders at zero: no start error from the mean load
    for enc in ("axis", "drive"):
        env = DSS14Env(encoders=enc, encoder_bits=None, **{**KW, "wind_direction": "front"})
        _, info = env.reset(seed=0)
        assert abs(info["servo_error_el_mdeg"]) < 1e-9 and abs(info["servo_error_az_mdeg"]) < 1e-9
        if enc == "axis":
            assert abs(info["pointing_error_el_mdeg"]) < 1e-9


@pytest.mark.parametrize("env_id", [p.env_id for p in PRESETS.values()] + list(WRAPPED_IDS))
def test_every_id_takes_the_encoders_key(env_id: str) -> None:
    env = gym.make(env_id, encoders="axis")
    assert env.unwrapped.config.encoders == "axis"
    env.reset(seed=0)
    _, r, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
    assert np.isfinite(r)


@pytest.mark.parametrize("env_id", [p.env_id for p in PRESETS.values()])
def test_every_id_takes_the_encoders_key_in_its_vector_version(env_id: str) -> None:
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", encoders="axis")
    assert venv.unwrapped.config.encoders == "axis"
    venv.reset(seed=0)
    assert np.all(np.isfinite(venv.step(np.zeros((2, 2), np.float32))[1]))


@pytest.mark.parametrize("value", ["axes", 2, None])
def test_bad_encoders_value_is_one_line_naming_the_key(value) -> None:
    with pytest.raises(ConfigError, match=r"^keyword arguments: field 'encoders': must") as err:
        DSS14Env(encoders=value)
    assert "\n" not in str(err.value)
