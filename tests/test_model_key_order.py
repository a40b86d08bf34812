"""The order of the keys of a model file never changes the model: a copy of configs/model.yaml
with every mapping's keys sorted (the same values) builds the same calibration and the same
environment, bit for bit.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.core.schema import default_config_path
from dss14_env.envs.plant import PLANT_FACTORIES, default_plant_factory


def _sorted(node: Any) -> Any:
    """``node`` with the keys of every mapping in it sorted, recursively (values unchanged)."""
    if isinstance(node, dict):
        return {k: _sorted(node[k]) for k in sorted(node, key=str)}
    if isinstance(node, list):
        return [_sorted(v) for v in node]
    return node


@pytest.fixture(scope="module")
def sorted_model(tmp_path_factory) -> Path:
    """configs/model.yaml with its keys sorted, every value the shipped one."""
    raw = yaml.safe_load(default_config_path("model.yaml").read_text(encoding="utf-8"))
    path = tmp_path_factory.mktemp("model") / "model_sorted.yaml"
    path.write_text(yaml.safe_dump(_sorted(raw), sort_keys=False), encoding="utf-8")
    assert list(yaml.safe_load(path.read_text(encoding="utf-8"))) == sorted(raw)
    return path


def test_sorted_copy_changes_the_order_of_the_gain_sets(sorted_model: Path) -> None:
    """The premise: the sorted copy lists the gain sets in another order than the shipped file."""
    shipped = default_plant_factory().model.cfg
    other = PLANT_FACTORIES.get(sorted_model).model.cfg
    assert list(other.gain_sets) != list(shipped.gain_sets)
    assert other.gain_sets == shipped.gain_sets


def test_sorted_copy_gives_the_same_calibration(sorted_model: Path) -> None:
    shipped = default_plant_factory().model.calibration
    other = PLANT_FACTORIES.get(sorted_model).model.calibration
    for f in dataclasses.fields(shipped):
        assert getattr(other, f.name) == getattr(shipped, f.name), f.name


def _run(env: gym.Env, seed: int, actions: np.ndarray) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        out.append(np.append(obs, reward))
        if terminated or truncated:
            break
    return np.concatenate(out)


@pytest.mark.parametrize("env_id", ["DSS14-v0", "DSS14-HoldFront-v0"])
def test_sorted_copy_gives_the_same_environment(sorted_model: Path, env_id: str) -> None:
    acts = np.random.default_rng(7).uniform(-0.05, 0.05, (300, 2)).astype(np.float32)
    shipped = gym.make(env_id)
    other = gym.make(env_id, model_config=sorted_model)
    a, b = _run(shipped, 11, acts), _run(other, 11, acts)
    assert a.shape == b.shape and a.size > 300
    np.testing.assert_array_equal(a, b)
