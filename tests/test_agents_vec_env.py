"""The SB3 VecEnv over the batched DSS14 vector env (agents/vec_env.py) and the batched policy
interface on top of it (agents/interface.py), against SB3's DummyVecEnv of single envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

import dss14_env  # noqa: F401
from dss14_env.agents.interface import InterfaceSpec, InterfaceWrapper
from dss14_env.agents.vec_env import InterfaceVecEnv, SB3VecEnv, make_sb3_vec_env

N = 4


def _pair(env_id: str, steps: int, seed: int, **kw):
    fast = make_sb3_vec_env(env_id, N, seed=seed, max_episode_steps=steps, **kw)
    slow = make_vec_env(lambda: gym.make(env_id, max_episode_steps=steps, **kw), n_envs=N,
                        seed=seed, vec_env_cls=DummyVecEnv)
    return fast, slow


def _compare(fast, slow, n_steps: int, actions) -> int:
    """Step both with the same actions; return how many episodes ended."""
    np.testing.assert_allclose(fast.reset(), slow.reset(), rtol=1e-5, atol=1e-6)
    ended = 0
    for k in range(n_steps):
        a = actions(k)
        of, rf, df, inf_ = fast.step(a)
        os_, rs, ds, ins = slow.step(a)
        np.testing.assert_array_equal(df, ds)
        np.testing.assert_allclose(of, os_, rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(rf, rs, rtol=1e-6, atol=1e-9)
        assert rf.dtype == np.float32
        for i in np.flatnonzero(ds):
            ended += 1
            np.testing.assert_allclose(inf_[i]["terminal_observation"], ins[i]["terminal_observation"],
                                       rtol=1e-5, atol=1e-5)
            assert inf_[i]["TimeLimit.truncated"] == ins[i]["TimeLimit.truncated"]
    return ended


@pytest.mark.parametrize("env_id, kw", [
    ("DSS14-Hold-v0", {}),
    ("DSS14-v0", {"wind_speed_kmh": 70.0}),
])
def test_same_episodes_as_dummy_vec_env_across_truncations(env_id: str, kw: dict) -> None:
    fast, slow = _pair(env_id, 40, seed=10_000, **kw)
    rng = np.random.default_rng(0)
    acts = rng.uniform(-0.05, 0.05, size=(130, N, 2)).astype(np.float32)
    ended = _compare(fast, slow, 130, lambda k: acts[k])
    assert ended == 3 * N  # three truncations per sub-environment, reset in the same step


def test_terminations_are_not_truncations() -> None:
    # a tight error limit and a full-rate command terminate the episodes early
    fast, slow = _pair("DSS14-Hold-v0", 500, seed=10_003, max_error_deg=0.005)
    a = np.tile(np.array([[1.0, -1.0]], np.float32), (N, 1))
    ended = _compare(fast, slow, 120, lambda k: a)
    assert ended >= N
    fast.reset()
    for _ in range(200):
        _, _, d, infos = fast.step(a)
        if d.any():
            i = int(np.flatnonzero(d)[0])
            assert infos[i]["TimeLimit.truncated"] is False
            break
    else:
        raise AssertionError("no episode terminated")


def test_works_under_vec_monitor_and_vec_normalize() -> None:
    venv = VecNormalize(VecMonitor(make_sb3_vec_env("DSS14-Hold-v0", N, seed=10_000,
                                                    max_episode_steps=25)))
    venv.reset()
    episodes = []
    for _ in range(60):
        obs, rew, done, infos = venv.step(np.zeros((N, 2), np.float32))
        assert obs.shape == (N, 12) and np.all(np.isfinite(obs))
        episodes += [inf["episode"] for inf in infos if "episode" in inf]
        for i in np.flatnonzero(done):
            assert infos[i]["terminal_observation"].shape == (12,)
    assert len(episodes) == 2 * N and all(e["l"] == 25 for e in episodes)
    assert venv.obs_rms.count > 60 * N


def test_refuses_other_ids_and_next_step_vector_envs() -> None:
    with pytest.raises(ValueError, match="not a DSS14 environment"):
        make_sb3_vec_env("Pendulum-v1", 2)
    with pytest.raises(ValueError, match="SAME_STEP"):
        SB3VecEnv(gym.make_vec("DSS14-Hold-v0", num_envs=2, vectorization_mode="vector_entry_point"))


@pytest.mark.parametrize("spec", [
    InterfaceSpec(base="pi", action="residual", history=3),
    InterfaceSpec(history=2),
    InterfaceSpec(base="lqg", action="residual", residual_scale=0.02),
])
def test_interface_vec_env_equals_the_wrapper_in_dummy_vec_env(spec: InterfaceSpec) -> None:
    steps = 30
    cfg = gym.make("DSS14-Hold-v0").unwrapped.config
    fast = InterfaceVecEnv(make_sb3_vec_env("DSS14-Hold-v0", 2, seed=10_000, max_episode_steps=steps),
                           spec, cfg)
    slow = make_vec_env(lambda: InterfaceWrapper(gym.make("DSS14-Hold-v0", max_episode_steps=steps),
                                                 spec), n_envs=2, seed=10_000, vec_env_cls=DummyVecEnv)
    assert fast.observation_space.shape == slow.observation_space.shape
    rng = np.random.default_rng(1)
    acts = rng.uniform(-1, 1, size=(70, 2, 2)).astype(np.float32)
    np.testing.assert_allclose(fast.reset(), slow.reset(), rtol=1e-5, atol=1e-6)
    ended = 0
    for k in range(70):
        of, rf, df, inf_ = fast.step(acts[k])
        os_, rs, ds, ins = slow.step(acts[k])
        np.testing.assert_array_equal(df, ds)
        np.testing.assert_allclose(of, os_, rtol=1e-4, atol=1e-5)
        np.testing.assert_allclose(rf, rs, rtol=1e-5, atol=1e-9)
        for i in np.flatnonzero(ds):
            ended += 1
            np.testing.assert_allclose(inf_[i]["terminal_observation"],
                                       ins[i]["terminal_observation"], rtol=1e-4, atol=1e-5)
    assert ended == 4
