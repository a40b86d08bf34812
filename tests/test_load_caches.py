"""What a process keeps after loading a file or designing a controller: the parsed
configuration texts (:func:`dss14_env.core.schema.parsed_config`), the checked policy files
(:func:`dss14_env.agents.policy.checked_policy`) and the LQG designs
(:func:`dss14_env.baselines.lqg.cached_lqg_design`) give the same values as a fresh load, never
a stale file's and never another caller's changes; the runner scores the same with them.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from dss14_env.agents.policy import DSS14_OBS_DIM, POLICIES_DIR, checked_policy, load_policy
from dss14_env.agents.storage import PolicyFileError, load_weights, save_weights
from dss14_env.baselines.interface import ControlInterface
from dss14_env.baselines.lqg import cached_lqg_design, lqg_design_from_config
from dss14_env.bench.report import without_timings
from dss14_env.bench.runner import run
from dss14_env.core.schema import config_path, load_yaml, parsed_config, read_config
from dss14_env.envs.config import load_env_config
from dss14_env.model.config import load_model_config


@pytest.mark.parametrize("name", ["model", "env", "controllers", "ppo"])
def test_read_config_equals_a_fresh_parse(name: str) -> None:
    path = config_path(name)
    fresh = load_yaml(path.read_text(encoding="utf-8"), str(path))
    first, _ = read_config(name)
    again, _ = read_config(name)  # from the parsed text
    assert first == fresh and again == fresh


def test_loaders_give_equal_objects_with_and_without_the_parsed_texts() -> None:
    parsed_config.cache_clear()
    model, env = load_model_config(), load_env_config()
    assert parsed_config.cache_info().currsize >= 1
    assert load_model_config() == model and load_env_config() == env
    parsed_config.cache_clear()
    assert load_model_config() == model and load_env_config() == env


def test_a_callers_changes_reach_no_other_caller() -> None:
    data, _ = read_config("model")
    data["board"]["changed"] = 1
    data.pop("structure")
    again, _ = read_config("model")
    assert "changed" not in again["board"] and "structure" in again


def _write(path: Path, text: str, mtime_ns: int) -> None:
    path.write_text(text, encoding="utf-8")
    os.utime(path, ns=(mtime_ns, mtime_ns))


def test_an_edited_file_is_read_anew(tmp_path: Path) -> None:
    f = tmp_path / "env_edit.yaml"
    # same size and the same modification time: only the content tells them apart
    _write(f, "wind_speed_kmh: 30.0\n", 1_000_000_000)
    assert read_config(f)[0] == {"wind_speed_kmh": 30.0}
    assert load_env_config(f).wind_speed_kmh == 30.0
    _write(f, "wind_speed_kmh: 40.0\n", 1_000_000_000)
    assert read_config(f)[0] == {"wind_speed_kmh": 40.0}
    assert load_env_config(f).wind_speed_kmh == 40.0


def test_a_broken_edit_is_refused_not_served_from_the_earlier_text(tmp_path: Path) -> None:
    f = tmp_path / "env_broken.yaml"
    _write(f, "wind_speed_kmh: 30.0\n", 1_000_000_000)
    read_config(f)
    _write(f, "wind_speed_kmh: [30.0\n", 1_000_000_000)
    with pytest.raises(ValueError, match="not valid YAML"):
        read_config(f)


def test_the_parsed_texts_are_capped() -> None:
    assert parsed_config.cache_info().maxsize is not None


# ------------------------------------------------------------------ policies
def _actions(ctrl, obs: np.ndarray) -> np.ndarray:
    ctrl.reset_batch(len(obs))
    return ctrl.act_batch(obs)


def _observations(n: int = 6) -> np.ndarray:
    rng = np.random.default_rng(3)
    return (0.3 * rng.standard_normal((n, DSS14_OBS_DIM))).astype(np.float32)


@pytest.mark.parametrize("name", ["residual_pi", "ppo_general"])
def test_a_policy_loaded_again_equals_a_fresh_load(name: str) -> None:
    folder = POLICIES_DIR / name
    checked_policy.cache_clear()
    fresh = load_policy(folder)
    again = load_policy(folder)
    assert checked_policy.cache_info().hits >= 1
    assert again.policy is not fresh.policy and again.stats is not fresh.stats  # each its own
    for key, value in fresh.policy.state_dict().items():
        assert torch.equal(value, again.policy.state_dict()[key])
    np.testing.assert_array_equal(again.stats.obs_mean, fresh.stats.obs_mean)
    obs = _observations()
    np.testing.assert_array_equal(_actions(again, obs), _actions(fresh, obs))


def test_a_controllers_changes_reach_no_other_load() -> None:
    ctrl = load_policy(POLICIES_DIR / "residual_pi")
    ctrl.stats.obs_mean[:] = 1e3
    with torch.no_grad():
        next(ctrl.policy.parameters()).add_(1.0)
    again = load_policy(POLICIES_DIR / "residual_pi")
    assert not np.any(again.stats.obs_mean == 1e3)
    assert not torch.equal(next(again.policy.parameters()), next(ctrl.policy.parameters()))


def test_an_edited_policy_file_is_read_anew(tmp_path: Path) -> None:
    folder = tmp_path / "policy"
    shutil.copytree(POLICIES_DIR / "residual_pi", folder)
    obs = _observations()
    before = _actions(load_policy(folder), obs)
    stamp = os.stat(folder / "policy.pt")
    fp, state = load_weights(folder / "policy.pt")
    key = next(k for k in state if k.startswith("action_net") and k.endswith("bias"))
    state = {**state, key: state[key] + 0.25}
    save_weights(folder / "policy.pt", state, fp)
    os.utime(folder / "policy.pt", ns=(stamp.st_atime_ns, stamp.st_mtime_ns))  # same time and size
    assert os.stat(folder / "policy.pt").st_size == stamp.st_size
    after = load_policy(folder)
    assert torch.equal(after.policy.state_dict()[key], state[key])
    assert not np.array_equal(_actions(after, obs), before)


def test_a_policy_file_broken_after_a_load_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "policy"
    shutil.copytree(POLICIES_DIR / "residual_pi", folder)
    load_policy(folder)
    (folder / "policy.pt").write_bytes(b"not a policy")
    with pytest.raises(PolicyFileError, match="policy.pt"):
        load_policy(folder)


# ------------------------------------------------------------------ LQG designs
def test_an_lqg_design_is_computed_once_and_read_only() -> None:
    iface = ControlInterface.default()
    cached_lqg_design.cache_clear()
    first = lqg_design_from_config(iface, wind=(10.0, 0.5))
    assert lqg_design_from_config(iface, wind=(10.0, 0.5)) is first
    assert not first.K.flags.writeable and not first.L.flags.writeable
    cached_lqg_design.cache_clear()
    fresh = lqg_design_from_config(iface, wind=(10.0, 0.5))
    assert fresh is not first
    np.testing.assert_array_equal(fresh.K, first.K)
    np.testing.assert_array_equal(fresh.L, first.L)
    other = lqg_design_from_config(iface, wind=(10.0, 0.6))
    assert not np.array_equal(other.K, first.K)


# ------------------------------------------------------------------ the bench's figures
def _clear_caches() -> None:
    parsed_config.cache_clear()
    checked_policy.cache_clear()
    cached_lqg_design.cache_clear()


def test_the_runner_scores_the_same_with_cold_and_warm_caches() -> None:
    rows = ["pi_kp1", "lqg", "lqg_pointing", "mpc", "ppo", "ppo_general"]
    kw = dict(seeds=[0, 1], steps=120, sequential_seeds=1, n_resamples=200)
    _clear_caches()
    cold = run(rows, ["hold_side", "step"], **kw)
    warm = run(rows, ["hold_side", "step"], **kw)
    assert _same(warm, cold)


def _same(a: dict, b: dict) -> bool:
    """Equal figures, bit for bit (NaN equal to NaN), timings left out."""
    return json.dumps(without_timings(a), sort_keys=True) == json.dumps(without_timings(b), sort_keys=True)
