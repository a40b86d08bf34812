"""Snapshots refused when they do not fit (``set_state``: class, number of sub-environments,
configuration, parts and shapes; one line, before anything changes), and the wrapper ids
restore what they show next after ``get_state`` / ``set_state`` of the unwrapped environment.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.envs.env import DSS14Env, EnvState
from dss14_env.envs.vector import DSS14VectorEnv

KW = dict(scenario="hold", wind_speed_kmh=50.0, wind_direction="side")


def _steps(env, n: int, seed: int = 0) -> list:
    acts = np.random.default_rng(seed).uniform(-0.05, 0.05, (n,) + env.action_space.shape).astype(np.float32)
    return [env.step(a)[:2] for a in acts]


def _refused(env, state, match: str) -> None:
    before = env.get_state()
    ref = _steps(env, 3)
    env.set_state(before)
    with pytest.raises(ValueError, match=match) as err:
        env.set_state(state)
    assert "\n" not in str(err.value)
    got = _steps(env, 3)  # nothing changed: the env continues as before the refused call
    for (o1, r1), (o2, r2) in zip(ref, got, strict=True):
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2)


def _cut(state: EnvState, drop: str) -> EnvState:
    return dataclasses.replace(state, data={k: v for k, v in state.data.items() if k != drop})


@pytest.mark.parametrize("other, match", [
    (dict(dt=0.01), "field 'dt' is 0.01 in the snapshot, 0.02 here"),
    (dict(scenario="step"), "field 'scenario' is 'step' in the snapshot, 'hold' here"),
    (dict(reward="pointing"), "field 'reward'"),
])
def test_single_env_refuses_a_snapshot_of_another_configuration(other: dict, match: str) -> None:
    src = DSS14Env(**{**KW, **other})
    src.reset(seed=1)
    env = DSS14Env(**KW)
    env.reset(seed=2)
    _refused(env, src.get_state(), match)


def test_single_env_refuses_empty_cut_off_and_misshaped_snapshots() -> None:
    env = DSS14Env(**KW)
    env.reset(seed=2)
    good = env.get_state()
    _refused(env, dataclasses.replace(good, data={}), "^state is incomplete")
    _refused(env, _cut(good, "_block"), r"^state is incomplete: 1 of its \d+ parts are missing \(_block\)")
    short = dataclasses.replace(good, data={**good.data, "_block": good.data["_block"][:, :-3]})
    _refused(env, short, "^state must hold the plant and step state of this model")
    _refused(env, EnvState("DSS14Env", {}), "^state must come from an environment of this configuration")
    _refused(env, dataclasses.replace(good, riders=(1,)), r"^state must hold the states of the 0 object")


@pytest.mark.parametrize("make, match", [
    (lambda: DSS14VectorEnv(num_envs=3, **KW),
     "^state must come from a DSS14VectorEnv with num_envs = 2, got a snapshot of num_envs = 3"),
    (lambda: DSS14VectorEnv(num_envs=2, **{**KW, "dt": 0.01}), "field 'dt'"),
    (lambda: DSS14Env(**KW),
     "^state must be an EnvState of a DSS14VectorEnv .*got an EnvState of a DSS14Env"),
])
def test_vector_env_refuses_a_snapshot_of_another_env(make, match: str) -> None:
    src = make()
    src.reset(seed=1)
    venv = DSS14VectorEnv(num_envs=2, **KW)
    venv.reset(seed=2)
    _refused(venv, src.get_state(), match)


def test_vector_env_refuses_cut_off_and_misshaped_snapshots() -> None:
    venv = DSS14VectorEnv(num_envs=2, **KW)
    venv.reset(seed=2)
    good = venv.get_state()
    _refused(venv, _cut(good, "_s"), r"^state is incomplete: .*\(_s\)")
    z = good.data["_Z"]  # the step buffers, one column per sub-environment
    _refused(venv, dataclasses.replace(good, data={**good.data, "_Z": z[..., :1]}),
             r"^state must hold 2 sub-environments of this model .*part\(s\) _Z have other shapes")


@pytest.mark.parametrize("env_id", ["DSS14-Residual-v0", "DSS14-Plain-v0", "DSS14-ResidualLQG-v0"])
def test_wrapper_ids_restore_their_next_observation_bit_for_bit(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=3)
    _steps(env, 20, seed=1)
    state = env.unwrapped.get_state()
    ref = _steps(env, 40, seed=2)
    for _ in range(2):  # any number of times
        env.unwrapped.set_state(state)
        got = _steps(env, 40, seed=2)
        for (o1, r1), (o2, r2) in zip(ref, got, strict=True):
            assert np.array_equal(o1, o2) and r1 == r2


# ---------------------------------------------------------------------------- hypothesis
@pytest.fixture(scope="module")
def snapshots() -> list[tuple]:
    """A single and a vector environment (two plants: a permutation), each with a good snapshot."""
    out = []
    for env in (DSS14Env(**KW), DSS14VectorEnv(num_envs=2, **{**KW, "wind_speed_kmh": "random"})):
        env.reset(seed=5)
        out.append((env, env.get_state()))
    return out


@st.composite
def damaged(draw, good: EnvState) -> EnvState:
    """A snapshot with parts missing, parts cut short, another configuration or foreign riders."""
    data = dict(good.data)
    kind = draw(st.sampled_from(["drop", "cut", "config", "riders", "num_envs"]))
    if kind == "drop":
        names = sorted(k for k in data if not k.startswith("_np_random"))  # the vector env's own seed
        for name in draw(st.lists(st.sampled_from(names), min_size=1, max_size=len(names), unique=True)):
            del data[name]
        return dataclasses.replace(good, data=data)
    if kind == "cut":
        arrays = sorted(k for k, v in data.items() if isinstance(v, np.ndarray) and v.ndim and v.shape[0] > 1)
        if not arrays:
            return dataclasses.replace(good, data={})
        name = draw(st.sampled_from(arrays))
        data[name] = data[name][:draw(st.integers(0, data[name].shape[0] - 1))]
        return dataclasses.replace(good, data=data)
    if kind == "config":
        key, value = draw(st.sampled_from([("dt", 0.01), ("scenario", "track"), ("reward", "pointing"),
                                           ("encoders", "axis"), ("wind_speed_kmh", 30.0)]))
        return dataclasses.replace(good, config=good.config.replace(**{key: value}))
    if kind == "riders":
        return dataclasses.replace(good, riders=good.riders + (draw(st.integers()),))
    return dataclasses.replace(good, num_envs=good.num_envs + draw(st.integers(1, 3)))


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_every_damaged_snapshot_is_refused_in_one_line(snapshots: list[tuple], data) -> None:
    for env, good in snapshots:
        bad = data.draw(damaged(good))
        with pytest.raises(ValueError) as err:
            env.set_state(bad)
        assert "\n" not in str(err.value) and str(err.value).startswith("state ")
