"""The agents' wrapper ids (``DSS14-Plain/Residual/ResidualLQG/KalmanObs-v0``) take their input
as the base ids do: one action check (strings, complex numbers, booleans, objects, other shapes
refused in the same words), one snapshot check (a snapshot of another id refused before anything
changes), and a refused first ``reset()`` leaves them usable.
"""

from __future__ import annotations

import copy
from fractions import Fraction

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.agents import AGENT_ENV_IDS
from dss14_env.envs.core import as_actions

WRAPPER_IDS = sorted(AGENT_ENV_IDS)
BAD_ACTIONS = ["ab", np.array(["0.5", "0.5"]), np.array([0.5 + 1j, 0.0]), [0.5 + 0j, 0.0],
               np.array([True, False]), np.zeros((2, 1)), np.zeros((1, 2)), [Fraction(1, 2), 0],
               [np.nan, 0.0], None, 0.5, [0.1, 0.2, 0.3]]


def _make(env_id: str) -> gym.Env:
    env = gym.make(env_id, max_episode_steps=200)
    env.reset(seed=0)
    return env


@pytest.fixture(scope="module")
def envs() -> dict[str, gym.Env]:
    """One environment of each wrapper id and of its base id, reset."""
    return {env_id: _make(env_id) for env_id in [*WRAPPER_IDS, "DSS14-Hold-v0"]}


def _message(env: gym.Env, action) -> str:
    with pytest.raises(ValueError, match="^action must") as info:
        env.step(action)
    return str(info.value)


@pytest.mark.parametrize("action", BAD_ACTIONS, ids=repr)
@pytest.mark.parametrize("env_id", WRAPPER_IDS)
def test_a_wrapper_refuses_what_the_base_id_refuses_in_its_words(envs, env_id: str, action) -> None:
    assert _message(envs[env_id], action) == _message(envs["DSS14-Hold-v0"], action)


@pytest.mark.parametrize("env_id", WRAPPER_IDS)
def test_a_refused_action_changes_nothing(env_id: str) -> None:
    env = _make(env_id)
    twin = copy.deepcopy(env)
    for action in BAD_ACTIONS:
        with pytest.raises(ValueError, match="^action must"):
            env.step(action)
    for _ in range(3):
        a, b = env.step(np.array([0.3, -0.2])), twin.step(np.array([0.3, -0.2]))
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]


@pytest.mark.parametrize("source, target", [(s, t) for t in WRAPPER_IDS
                                             for s in [*WRAPPER_IDS, "DSS14-Hold-v0"] if s != t])
def test_a_snapshot_of_another_id_is_refused_before_anything_changes(envs, source: str, target: str) -> None:
    """(Its own snapshot restores it bit for bit: tests/test_env_state.py.)"""
    env = _make(target)
    mine = env.unwrapped.get_state()
    with pytest.raises(ValueError, match="^state must"):
        env.unwrapped.set_state(envs[source].unwrapped.get_state())
    twin = _make(target)
    twin.unwrapped.set_state(mine)
    for _ in range(3):  # the refused snapshot left it as it was
        a, b = env.step(np.array([0.1, 0.1])), twin.step(np.array([0.1, 0.1]))
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]


@pytest.mark.parametrize("bad", [dict(seed=-1), dict(seed="x"), dict(options={"bogus": 1})], ids=repr)
@pytest.mark.parametrize("env_id", [*WRAPPER_IDS, "DSS14-Hold-v0"])
def test_after_a_refused_first_reset_the_env_resets_and_steps(env_id: str, bad: dict) -> None:
    env = gym.make(env_id)
    with pytest.raises(ValueError):
        env.reset(**bad)
    obs, _ = env.reset(seed=1)
    for _ in range(2):
        obs, reward, *_ = env.step(env.action_space.sample())
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)


# ---------------------------------------------------------------------------- hypothesis
numbers = st.one_of(st.floats(), st.integers(-10**30, 10**30), st.sampled_from([0, 1, -1, 0.5, 1e300]))
actions = st.one_of(
    hnp.arrays(st.sampled_from([np.float32, np.float64, np.int64, np.bool_, np.complex128, np.uint8]),
               st.sampled_from([(2,), (1, 2), (2, 1), (3,), ()])),
    st.lists(st.one_of(numbers, st.text(max_size=2), st.none(), st.booleans()), max_size=3),
    st.one_of(numbers, st.none(), st.text(max_size=3)))


@pytest.mark.parametrize("env_id", WRAPPER_IDS)
@given(action=actions)
def test_wrapper_actions_of_any_kind(envs, env_id: str, action) -> None:
    """Refused exactly when the base ids' check refuses it, in its words; otherwise a finite step."""
    env = envs[env_id]
    try:
        as_actions(action, (2,))
    except ValueError as exc:
        with pytest.raises(ValueError) as info:
            env.step(action)
        assert str(info.value) == str(exc)
        return
    obs, reward, terminated, truncated, _ = env.step(action)
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)
    if terminated or truncated:
        env.reset(seed=2)


reset_args = st.fixed_dictionaries({}, optional={
    "seed": st.one_of(st.none(), st.integers(-5, 2**70), st.booleans(), st.floats(), st.text(max_size=2)),
    "options": st.one_of(st.none(), st.text(max_size=2), st.dictionaries(
        st.sampled_from(["wind_speed_kmh", "wind_direction", "scenario", "bogus", "params"]),
        st.one_of(st.floats(), st.integers(-10, 10**9), st.text(max_size=3), st.none()), max_size=2)),
})


@pytest.mark.parametrize("env_id", WRAPPER_IDS)
@given(args=reset_args)
def test_wrapper_resets_of_any_kind(envs, env_id: str, args: dict) -> None:
    """A reset is refused (ValueError naming the input) or gives a finite observation; either
    way the environment resets and steps afterwards.
    """
    env = envs[env_id]
    try:
        obs, _ = env.reset(**args)
    except ValueError as exc:
        assert "\n" not in str(exc)
    else:
        assert np.all(np.isfinite(obs))
    env.reset(seed=3)
    obs, reward, *_ = env.step(np.array([0.1, -0.1]))
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)
