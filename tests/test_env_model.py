"""The environments run on their own model: ``model_config=`` a model YAML builds the model and
calibrates its wind loads (once per file and content: :data:`dss14_env.envs.plant.PLANT_FACTORIES`)."""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.core.schema import ConfigError, default_config_path
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.plant import PLANT_FACTORIES, PlantFactory, default_plant_factory
from dss14_env.envs.vector import DSS14VectorEnv
from dss14_env.model.uncertainty import SWEEP_PARAMS


@pytest.fixture(scope="module")
def heavy_dish(tmp_path_factory) -> Path:
    """configs/model.yaml with the reflector's rib node mass x 1.5 (built once for the module)."""
    text = default_config_path("model.yaml").read_text()
    new, n = re.subn(r"(rib_node_mass:\s*\{value:\s*)([0-9.eE+]+)",
                     lambda m: m.group(1) + repr(float(m.group(2)) * 1.5), text)
    assert n == 1
    path = tmp_path_factory.mktemp("model") / "heavy_dish.yaml"
    path.write_text(new)
    PLANT_FACTORIES.get(path)  # a few seconds: the calibration
    return path


def _encoders(env, seed: int, actions: np.ndarray) -> np.ndarray:
    env.reset(seed=seed)
    out = []
    for a in actions:
        obs, _, _, _, info = env.step(a)
        out.append((info["servo_error_az_mdeg"], info["servo_error_el_mdeg"]))
    return np.array(out)


def test_a_heavier_dish_changes_the_dynamics(heavy_dish: Path) -> None:
    acts = np.tile(np.array([[0.02, -0.02]], np.float32), (300, 1))
    heavy = gym.make("DSS14-HoldFront-v0", model_config=heavy_dish)
    nominal = gym.make("DSS14-HoldFront-v0")
    factory = heavy.unwrapped.plants
    assert factory is PLANT_FACTORIES.get(heavy_dish) and factory is not default_plant_factory()
    assert factory.model.cfg.structure.rib_node_mass == pytest.approx(
        1.5 * default_plant_factory().model.cfg.structure.rib_node_mass)
    a, b = _encoders(heavy, 4, acts), _encoders(nominal, 4, acts)
    assert np.all(np.isfinite(a))
    assert np.max(np.abs(a - b)) > 1e-3  # mdeg: other structural modes, other response
    assert not np.allclose(heavy.unwrapped.episode.plant.Ad, nominal.unwrapped.episode.plant.Ad)


def test_single_and_vector_envs_agree_on_a_user_model(heavy_dish: Path) -> None:
    N, T = 2, 300
    acts = np.random.default_rng(3).uniform(-0.05, 0.05, (T, N, 2)).astype(np.float32)
    venv = gym.make_vec("DSS14-Hold-v0", num_envs=N, vectorization_mode="vector_entry_point",
                        model_config=str(heavy_dish))
    assert isinstance(venv, DSS14VectorEnv) and venv.plants is PLANT_FACTORIES.get(heavy_dish)
    venv.reset(seed=10)
    v = np.array([venv.step(acts[t])[1] for t in range(T)])
    for i in range(N):
        env = DSS14Env(model_config=heavy_dish, scenario="hold", wind_direction="random",
                       wind_direction_grid_deg=[0.0, 90.0])
        env.reset(seed=10 + i)
        s = np.array([env.step(acts[t, i])[1] for t in range(T)])
        np.testing.assert_allclose(s, v[:, i], rtol=1e-9, atol=1e-12)


def test_parameter_draws_use_the_envs_own_model(heavy_dish: Path) -> None:
    env = DSS14Env(model_config=heavy_dish, scenario="hold", randomize_params=True)
    _, info = env.reset(seed=1)
    factory = env.plants
    assert set(info["params"]) == set(SWEEP_PARAMS)
    for name, v in info["params"].items():
        lo, hi = factory.model.cfg.params[name].range
        assert lo <= v <= hi
    assert any(p is env.episode.plant for p in factory._plants.values())
    assert not any(p is env.episode.plant for p in default_plant_factory()._plants.values())


def test_an_env_on_a_user_model_pickles_and_continues(heavy_dish: Path) -> None:
    env = DSS14Env(model_config=heavy_dish)
    env.reset(seed=2)
    twin = pickle.loads(pickle.dumps(env))
    assert twin.plants is env.plants  # found again by its file
    acts = np.random.default_rng(0).uniform(-0.1, 0.1, (50, 2))
    for a in acts:
        assert env.step(a)[1] == twin.step(a)[1]


@pytest.mark.parametrize("model_config, error, match", [
    ("no/such/model.yaml", ConfigError, "no/such/model.yaml"),
    (42, ValueError, "model_config must be"),
])
def test_a_bad_model_config_is_refused(model_config, error, match: str) -> None:
    with pytest.raises(error, match=match):
        DSS14Env(model_config=model_config)


def test_a_shared_factory_is_used_as_given() -> None:
    factory = PlantFactory(default_plant_factory().model, default_plant_factory().loads)
    env = DSS14Env(model_config=factory, scenario="hold")
    env.reset(seed=0)
    assert env.plants is factory and len(factory) == 1
    with pytest.raises(TypeError, match="model file"):  # no file to find it again by
        pickle.dumps(env)
    assert pickle.loads(pickle.dumps(DSS14Env())).plants is default_plant_factory()


@pytest.mark.parametrize("params, match", [
    ({"hydraulics.zeta_o": 5.0}, "params.hydraulics.zeta_o"),
    ({"hydraulics.beta": 1.0}, "params"),
])
def test_fixed_parameters_outside_the_models_ranges_are_refused(params: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        DSS14Env(params=params)
    env = DSS14Env()
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options={"params": params})


def test_a_model_file_is_parsed_once_per_content(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """PlantFactories.get reads a model file's YAML once per content, not on every call."""
    from types import SimpleNamespace

    from dss14_env.envs import plant

    parsed = []
    real = plant.load_model_config
    monkeypatch.setattr(plant, "load_model_config", lambda p=None: parsed.append(p) or real(p))
    monkeypatch.setattr(plant, "build_model", lambda cfg: SimpleNamespace(cfg=cfg))  # no model build
    monkeypatch.setattr(plant, "default_wind_loads", lambda: "shipped loads")
    path = tmp_path / "model.yaml"
    path.write_text(default_config_path("model.yaml").read_text())
    factories = plant.PlantFactories()
    first = factories.get(path)
    assert factories.get(path) is first and factories.get(str(path), False) is first
    assert len(parsed) == 1
    path.write_text(path.read_text() + "\n# edited\n")
    assert factories.get(path) is not first and len(parsed) == 2
