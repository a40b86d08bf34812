"""Copies of the environments continue bit for bit as the original: ``copy.deepcopy``, a pickle
round trip and ``get_state`` / ``set_state``, for every registered variant, single and vector."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.envs.env import DSS14Env, EnvState
from dss14_env.envs.presets import PRESETS
from dss14_env.envs.vector import DSS14VectorEnv

IDS = [p.env_id for p in PRESETS.values()]


def _run(env, actions: np.ndarray) -> list:
    """Step through ``actions`` (resetting a single env when its episode ends); everything seen."""
    out = []
    for a in actions:
        obs, rew, term, trunc, info = env.step(a)
        out.append((np.array(obs), np.array(rew), np.array(term), np.array(trunc),
                    {k: np.array(v) for k, v in info.items()}))
        if np.ndim(term) == 0 and (term or trunc):
            obs, info = env.reset()
            out.append((np.array(obs), {k: np.array(v) for k, v in info.items() if k != "params"}))
    return out


def _same(a: list, b: list) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        for u, v in zip(x, y, strict=True):
            if isinstance(u, dict):
                assert u.keys() == v.keys()
                for key in u:
                    np.testing.assert_array_equal(u[key], v[key], err_msg=key)
            else:
                np.testing.assert_array_equal(u, v)


def test_deepcopy_and_pickle_probe_copies_move_like_the_original() -> None:
    # after 100 zero steps and 200 at full rate the encoders have moved about half a degree;
    # copies taken after reset once stayed at their start reading and never terminated
    env = gym.make("DSS14-v0")
    env.reset(seed=0)
    envs = [env, copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    ends = []
    for e in envs:
        for _ in range(100):
            e.step(np.zeros(2, np.float32))
        for _ in range(200):
            obs, rew, term, _, _ = e.step(np.ones(2, np.float32))
        ends.append((obs[8:10].tolist(), rew, term))
    assert min(abs(v) for v in ends[0][0]) > 0.3  # deg: the original moved
    assert ends[1] == ends[0] and ends[2] == ends[0]


@pytest.mark.parametrize("env_id", IDS)
def test_single_env_copies_continue_bit_for_bit(env_id: str) -> None:
    env = gym.make(env_id, encoder_noise_mdeg=0.05)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    warm = rng.uniform(-0.3, 0.3, (40, 2)).astype(np.float32)
    acts = rng.uniform(-1, 1, (300, 2)).astype(np.float32)
    _run(env, warm)
    state = env.unwrapped.get_state()
    copies = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    ref = _run(env, acts)  # crosses a noise block (256 steps) and, for some ids, an episode end
    for c in copies:
        _same(_run(c, acts), ref)
    assert not any(len(r) == 5 and r[3] for r in ref)  # no truncation: the wrapper's count plays no part
    for _ in range(2):  # back in time, twice: the snapshot stays intact
        env.unwrapped.set_state(state)
        _same(_run(env.unwrapped, acts), ref)


def test_state_of_another_class_or_object_is_refused() -> None:
    env = DSS14Env()
    with pytest.raises(RuntimeError, match="reset"):
        env.get_state()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="state must be"):
        env.set_state({"x": 1})
    with pytest.raises(ValueError, match="state must be"):
        env.set_state(EnvState("DSS14VectorEnv", {}))


@pytest.mark.parametrize("env_id", IDS)
def test_vector_env_copies_continue_bit_for_bit(env_id: str) -> None:
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", max_episode_steps=120,
                        encoder_noise_mdeg=0.05)
    venv.reset(seed=5)
    rng = np.random.default_rng(1)
    acts = rng.uniform(-0.5, 0.5, (300, 3, 2)).astype(np.float32)
    _run(venv, acts[:30])
    state = venv.get_state()
    copies = [copy.deepcopy(venv), pickle.loads(pickle.dumps(venv))]
    ref = _run(venv, acts)  # autoresets at 120 steps, noise blocks at 256
    for c in copies:
        _same(_run(c, acts), ref)
    for _ in range(2):
        venv.set_state(state)
        _same(_run(venv, acts), ref)


def test_vector_state_restores_into_a_copy() -> None:
    venv = DSS14VectorEnv(num_envs=2, max_episode_steps=50, scenario="hold", wind_speed_kmh="random")
    venv.reset(seed=0)
    other = copy.deepcopy(venv)
    state = venv.get_state()
    acts = np.random.default_rng(2).uniform(-1, 1, (80, 2, 2))
    ref = _run(venv, acts)
    _run(other, acts[:10])
    other.set_state(state)
    _same(_run(other, acts), ref)


def test_copies_of_a_rendering_env_draw_the_same_picture() -> None:
    env = DSS14Env(render_mode="rgb_array", scenario="hold")
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.full(2, 0.01))
    frame = env.render()  # the figure exists now; copies draw their own
    for c in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):
        np.testing.assert_array_equal(c.render(), frame)
        c.step(np.zeros(2))
        env_next = copy.deepcopy(env)
        env_next.step(np.zeros(2))
        np.testing.assert_array_equal(c.render(), env_next.render())
