"""Policy files are read back without running code from them, and bad files are named
(agents/storage.py, agents/policy.py).

A planted pickle payload writes a marker file when it is unpickled: the tests check that the
marker never appears unless the caller opted in with ``trust_pickle=True``.
"""

from __future__ import annotations

import base64
import json
import os
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from dss14_env.agents.policy import DEFAULT_POLICY, load_policy
from dss14_env.agents.storage import (
    PolicyFileError,
    convert_sb3_policy,
    find_policy_files,
    load_stats,
    load_weights,
    policy_problem,
)
from dss14_env.agents.train import train
from dss14_env.cli import main


class Payload:
    """Unpickling this runs ``os.makedirs(marker)``: the marker shows that code ran."""

    def __init__(self, marker: Path) -> None:
        self.marker = str(marker)

    def __reduce__(self):
        return (os.makedirs, (self.marker,))


def tiny(**changes):
    cfg = dict(env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=128, seed=0,
               n_steps=64, batch_size=64, n_epochs=1, net_arch=[8], eval_freq=0,
               checkpoint_freq=0, progress_bar=False, verbose=0)
    cfg.update(changes)
    return cfg


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return train(tiny(), run_dir=tmp_path_factory.mktemp("store") / "run")


@pytest.fixture(scope="module")
def other_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return train(tiny(seed=1), run_dir=tmp_path_factory.mktemp("store") / "other")


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _sb3_folder(tmp_path: Path, marker: Path) -> Path:
    """A stable-baselines3 style folder whose model.zip and vecnormalize.pkl carry payloads."""
    folder = tmp_path / "sb3"
    folder.mkdir()
    _plant_zip(folder / "model.zip", marker)
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    return folder


def _plant_zip(path: Path, marker: Path) -> None:
    """An SB3 .zip whose ``data`` entry holds a serialised (pickled) payload, where SB3's
    loader unpickles class entries."""
    blob = base64.b64encode(pickle.dumps(Payload(marker))).decode()
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("data", json.dumps({"policy_class": {":type:": "x", ":serialized:": blob}}))


def test_planted_pickles_in_a_policy_folder_never_run(run: Path, tmp_path: Path) -> None:
    marker = tmp_path / "PWNED"
    folder = _copy(run, tmp_path / "policy")
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    _plant_zip(folder / "model.zip", marker)
    ctrl = load_policy(folder)
    assert ctrl.act(np.zeros(3, np.float32)).shape == (1,)
    assert policy_problem(folder) is None
    assert not marker.exists()


def test_a_foreign_pickle_is_refused_without_opt_in(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    marker = tmp_path / "PWNED"
    folder = _sb3_folder(tmp_path, marker)
    for path in (folder, folder / "model.zip"):
        with pytest.raises(PolicyFileError) as err:
            load_policy(path)
        msg = str(err.value)
        assert "\n" not in msg and str(folder / "model.zip") in msg and "trust_pickle" in msg
        assert "--trust-pickle" in msg
    assert "trust_pickle" in policy_problem(folder)
    with pytest.raises(ValueError, match="trust_pickle"):
        train(tiny(), run_dir=tmp_path / "r", resume=folder / "model.zip")
    assert main(["train", "ppo", "--config", "ppo_smoke", "--resume", str(folder / "model.zip"),
                 "--out", str(tmp_path / "r2")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--trust-pickle" in err
    assert main(["bench", "--controllers", "ppo", "--ppo-model", str(folder), "--quick",
                 "--out", str(tmp_path / "b")]) == 2
    capsys.readouterr()
    assert not marker.exists()
    # opted in, the pickle is unpickled: the payload runs (which is why it needs the opt-in)
    with pytest.raises(PolicyFileError):
        load_policy(folder, trust_pickle=True)
    assert marker.exists()


def test_a_payload_inside_policy_pt_is_refused(run: Path, tmp_path: Path) -> None:
    marker = tmp_path / "PWNED"
    folder = _copy(run, tmp_path / "policy")
    torch.save({"format": "dss14-policy-1", "state_dict": {}, "x": Payload(marker)},
               folder / "policy.pt")
    with pytest.raises(PolicyFileError, match=r"policy\.pt: not a readable policy weights file"):
        load_policy(folder)
    assert not marker.exists()


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty"])
def test_corrupt_files_are_named(run: Path, tmp_path: Path, damage: str) -> None:
    for name, match in (("policy.pt", "policy weights"), ("normalization.npz", "normalisation")):
        folder = _copy(run, tmp_path / f"{name}-{damage}")
        f = folder / name
        data = f.read_bytes()
        f.write_bytes({"truncate": data[:len(data) // 2], "garbage": b"\x00garbage" * 50,
                       "empty": b""}[damage])
        with pytest.raises(PolicyFileError) as err:
            load_policy(folder)
        assert str(f) in str(err.value) and match in str(err.value)
        assert "\n" not in str(err.value)


def test_weights_and_statistics_of_different_runs_are_refused(run: Path, other_run: Path,
                                                              tmp_path: Path) -> None:
    folder = _copy(run, tmp_path / "mixed")
    shutil.copy(other_run / "normalization.npz", folder / "normalization.npz")
    with pytest.raises(PolicyFileError, match="belongs to another run") as err:
        load_policy(folder)
    assert str(folder / "normalization.npz") in str(err.value)
    assert str(folder / "policy.pt") in str(err.value)


def test_weights_that_do_not_fit_the_config_are_named(run: Path, tmp_path: Path) -> None:
    folder = _copy(run, tmp_path / "arch")
    text = (folder / "config.yaml").read_text().replace("- 8\n", "- 16\n")
    (folder / "config.yaml").write_text(text)
    with pytest.raises(PolicyFileError, match="do not fit the architecture") as err:
        load_policy(folder)
    assert str(folder / "policy.pt") in str(err.value)


def test_policy_folder_layout_is_explicit(run: Path, tmp_path: Path) -> None:
    # a folder with weights but without config.yaml: no search in the folders above it
    outer = tmp_path / "outer"
    inner = outer / "a" / "b"
    inner.mkdir(parents=True)
    shutil.copy(run / "config.yaml", outer / "config.yaml")
    shutil.copy(run / "policy.pt", inner / "policy.pt")
    with pytest.raises(PolicyFileError, match="config.yaml is missing"):
        find_policy_files(inner)
    # normalised run without its statistics
    folder = _copy(run, tmp_path / "nostats")
    (folder / "normalization.npz").unlink()
    with pytest.raises(PolicyFileError, match="normalization.npz is missing"):
        load_policy(folder)
    files = find_policy_files(run / "eval" / "best") if (run / "eval" / "best").is_dir() else None
    assert files is None or files.weights.name == "policy.pt"


def test_the_shipped_policy_is_in_the_safe_format() -> None:
    names = sorted(p.name for p in DEFAULT_POLICY.iterdir())
    assert "policy.pt" in names and "normalization.npz" in names and "config.yaml" in names
    assert not any(n.endswith((".pkl", ".zip")) for n in names)
    wfp, _ = load_weights(DEFAULT_POLICY / "policy.pt")
    sfp, stats = load_stats(DEFAULT_POLICY / "normalization.npz")
    assert wfp["run_id"] == sfp["run_id"] and wfp["obs_dim"] == stats.obs_mean.size == 46


def test_convert_a_trusted_sb3_policy(tmp_path: Path) -> None:
    """An SB3 run folder (model.zip + vecnormalize.pkl written by SB3) converts once, with the
    opt-in, into a policy folder that acts identically."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    venv = VecNormalize(make_vec_env("Pendulum-v1", n_envs=2, seed=0))
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu",
                policy_kwargs={"net_arch": [8]})
    model.learn(128)
    src = tmp_path / "sb3run"
    src.mkdir()
    model.save(src / "model.zip")
    venv.save(str(src / "vecnormalize.pkl"))
    import yaml
    (src / "config.yaml").write_text(yaml.safe_dump(tiny(net_arch=[8])))
    with pytest.raises(PolicyFileError, match="trust_pickle"):
        convert_sb3_policy(src, tmp_path / "new")
    new = convert_sb3_policy(src, tmp_path / "new", trust_pickle=True)
    old_ctrl = load_policy(src, trust_pickle=True)
    new_ctrl = load_policy(new)
    rng = np.random.default_rng(1)
    obs = rng.uniform([-1, -1, -8], [1, 1, 8], size=(200, 3)).astype(np.float32)
    old_ctrl.reset_batch(200)
    new_ctrl.reset_batch(200)
    np.testing.assert_array_equal(old_ctrl.act_batch(obs), new_ctrl.act_batch(obs))
