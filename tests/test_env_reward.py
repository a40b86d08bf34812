"""The ``reward`` key: what the reward scores (the servo error at the encoders, or the dish's
true pointing error), the observation unchanged.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.core.schema import ConfigError
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.presets import PRESETS, WRAPPED_IDS
from dss14_env.envs.vector import DSS14VectorEnv

KW = dict(scenario="hold", wind_speed_kmh=50.0, wind_direction="side", action_change_weight=2.0)


def _expected(info: dict, a: np.ndarray, a_prev: np.ndarray, scale: float = 10.0, w: float = 2.0) -> float:
    """The documented quadratic on the pointing errors of the info."""
    p2 = info["pointing_error_el_mdeg"] ** 2 + info["pointing_error_xel_mdeg"] ** 2
    return -(p2 / scale**2 + w * float(np.sum((a - a_prev) ** 2)))


def test_pointing_reward_is_the_quadratic_of_the_pointing_errors() -> None:
    env = DSS14Env(reward="pointing", **KW)
    env.reset(seed=4)
    a_prev = None
    for a in ([0.0, 0.0], [0.002, -0.001], [0.003, 0.004], [-0.01, 0.0]):
        a = np.array(a, np.float32)
        _, r, _, _, info = env.step(a)
        if a_prev is not None:
            assert r == pytest.approx(_expected(info, a.astype(np.float64), a_prev), rel=1e-9)
        a_prev = a.astype(np.float64)


def test_pointing_reward_keeps_the_observation_and_changes_only_the_reward() -> None:
    acts = np.random.default_rng(0).uniform(-0.02, 0.02, (300, 2))
    servo, point = DSS14Env(**KW), DSS14Env(reward="pointing", **KW)
    o1, _ = servo.reset(seed=7)
    o2, _ = point.reset(seed=7)
    assert np.array_equal(o1, o2)
    r1, r2 = [], []
    for a in acts:
        o1, ra, *_ = servo.step(a)
        o2, rb, *_ = point.step(a)
        assert np.array_equal(o1, o2)
        r1.append(ra)
        r2.append(rb)
    # the dish swings more than the encoder in side wind: the pointing reward is the lower one
    assert np.mean(r2) < np.mean(r1)


def test_vector_env_pointing_reward_equals_the_single_env() -> None:
    N, T = 3, 300
    acts = np.random.default_rng(1).uniform(-0.02, 0.02, (T, N, 2))
    venv = DSS14VectorEnv(num_envs=N, reward="pointing", **KW)
    venv.reset(seed=3)
    v = np.array([venv.step(acts[t])[1] for t in range(T)])
    for i in range(N):
        env = DSS14Env(reward="pointing", **KW)
        env.reset(seed=3 + i)
        s = np.array([env.step(acts[t, i])[1] for t in range(T)])
        # the single env steps the 64-state restriction of the vector env's plant: rounding
        # apart, largest relative difference 1.6e-11 / 1.5e-10 / 1.2e-9 under OpenBLAS's
        # Haswell / SkylakeX / Sandybridge kernels
        np.testing.assert_allclose(s, v[:, i], rtol=1e-8, atol=1e-12)


@pytest.mark.parametrize("env_id", [p.env_id for p in PRESETS.values()] + list(WRAPPED_IDS))
def test_every_id_takes_the_reward_key(env_id: str) -> None:
    env = gym.make(env_id, reward="pointing")
    assert env.unwrapped.config.reward == "pointing"
    env.reset(seed=0)
    _, r, *_ , info = env.step(np.zeros(env.action_space.shape, np.float32))
    assert np.isfinite(r) and "pointing_error_xel_mdeg" in info


@pytest.mark.parametrize("env_id", [p.env_id for p in PRESETS.values()])
def test_every_id_takes_the_reward_key_in_its_vector_version(env_id: str) -> None:
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", reward="pointing")
    assert venv.unwrapped.config.reward == "pointing"


@pytest.mark.parametrize("value", ["beam", 1, None])
def test_bad_reward_value_is_one_line_naming_the_key(value) -> None:
    with pytest.raises(ConfigError, match=r"^keyword arguments: field 'reward': must") as err:
        DSS14Env(reward=value)
    assert "\n" not in str(err.value)
