"""PPO training infrastructure (agents/ppo.py, agents/policy.py, ``dss14 train ppo``).

Everything runs on Gymnasium's Pendulum-v1 (the DSS14-v0 environment is configured by the
shipped configs/ppo.yaml only) with a few hundred steps, so the whole file takes seconds.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

from dss14_env.agents.policy import DEFAULT_POLICY, PPOController, evaluate, load_policy
from dss14_env.agents.ppo import PPOConfig, default_config_path, load_config, train, vecnormalize_path_for
from dss14_env.cli import main

UNIT_PENDULUM = "PendulumUnitAction-v0"  # Pendulum with actions rescaled to [-1, 1], like DSS14-v0


def _unit_pendulum(**kwargs: Any) -> gym.Env:
    one = np.ones(1, dtype=np.float32)
    return gym.wrappers.RescaleAction(gym.make("Pendulum-v1", **kwargs), -one, one)


if UNIT_PENDULUM not in gym.registry:
    gym.register(UNIT_PENDULUM, entry_point=_unit_pendulum)


def tiny(**changes: Any) -> dict[str, Any]:
    """A 512-step, 2-env Pendulum run with evaluation and checkpoints every 256 steps."""
    cfg = dict(env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=512, seed=0,
               n_steps=64, batch_size=64, n_epochs=2, net_arch=[32, 32], eval_freq=256,
               n_eval_episodes=1, eval_seeds=[7, 8], checkpoint_freq=256, progress_bar=False,
               verbose=0)
    cfg.update(changes)
    return cfg


def _params(path: Path) -> dict[str, np.ndarray]:
    from stable_baselines3 import PPO

    model = PPO.load(path, device="cpu")
    return {k: v.detach().numpy().copy() for k, v in model.policy.state_dict().items()}


@pytest.fixture(scope="module")
def pendulum_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return train(tiny(), run_dir=tmp_path_factory.mktemp("ppo") / "run")


# ---------------------------------------------------------------------------------- config
def test_shipped_configs_load_and_round_trip() -> None:
    cfg = load_config()
    assert cfg.env_id == "DSS14-Residual-v0" and cfg.env_module == "dss14_env.agents.residual"
    # the shipped policy was trained with exactly the shipped config (docs/ppo.md)
    assert load_config(DEFAULT_POLICY / "config.yaml") == cfg
    assert load_config(default_config_path("ppo_plain.yaml")).env_id == "DSS14-Hold-v0"
    assert cfg.source == str(default_config_path())
    assert cfg.batch_size <= cfg.n_steps * cfg.n_envs
    smoke = load_config(default_config_path("ppo_smoke.yaml"))
    assert smoke.env_id == "Pendulum-v1"
    assert PPOConfig.from_dict(yaml.safe_load(yaml.safe_dump(cfg.to_dict()))) == cfg
    assert PPOConfig.from_dict({"learning_rate": "3e-4"}).learning_rate == 3e-4  # YAML 1.1 string


@pytest.mark.parametrize("bad, key", [
    ({"n_env": 8}, "n_env"),                       # typo of a key
    ({"n_envs": 0}, "n_envs"),
    ({"vec_env": "threads"}, "vec_env"),
    ({"gamma": 1.5}, "gamma"),
    ({"learning_rate": -1e-3}, "learning_rate"),
    ({"batch_size": 100}, "batch_size"),           # does not divide 8 * 256
    ({"eval_seeds": []}, "eval_seeds"),
    ({"net_arch": [64, "wide"]}, "net_arch"),
    ({"net_arch": {"pi": [64]}}, "net_arch"),
    ({"normalize_obs": "yes"}, "normalize_obs"),
    ({"total_timesteps": 1.5}, "total_timesteps"),
    ({"activation_fn": "sigmoid"}, "activation_fn"),
    ({"eval_env_kwargs": [1, 2]}, "eval_env_kwargs"),
])
def test_config_errors_name_key_and_file(tmp_path: Path, bad: dict, key: str) -> None:
    path = tmp_path / "ppo_bad.yaml"
    path.write_text(yaml.safe_dump({"env_id": "Pendulum-v1", **bad}))
    with pytest.raises(ValueError, match=f"'{key}'") as err:
        load_config(path)
    assert str(path) in str(err.value)


def test_config_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="not found: .*missing.yaml"):
        load_config(tmp_path / "missing.yaml")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="list.yaml: expected a mapping"):
        load_config(tmp_path / "list.yaml")
    with pytest.raises(ValueError, match="'env_id': cannot make 'NoSuchEnv-v0'"):
        train(tiny(env_id="NoSuchEnv-v0"), run_dir=tmp_path / "run")
    assert not (tmp_path / "run").exists()


# -------------------------------------------------------------------------------- training
def test_train_writes_every_output(pendulum_run: Path) -> None:
    run = pendulum_run
    for f in ("config.yaml", "model.zip", "vecnormalize.pkl", "train_summary.json",
              "checkpoints/ppo_256_steps.zip", "checkpoints/ppo_vecnormalize_256_steps.pkl",
              "checkpoints/ppo_512_steps.zip", "checkpoints/ppo_vecnormalize_512_steps.pkl",
              "eval/evaluations.npz", "eval/best/model.zip", "eval/best/vecnormalize.pkl",
              "monitor/0.monitor.csv", "monitor/1.monitor.csv"):
        assert (run / f).is_file(), f
    assert any((run / "tb").rglob("events.out.tfevents.*"))  # tensorboard is in the dev venv
    assert load_config(run / "config.yaml") == PPOConfig.from_dict(tiny())
    assert json.loads((run / "train_summary.json").read_text())["num_timesteps"] == 512
    with np.load(run / "eval/evaluations.npz") as d:
        assert d["timesteps"].tolist() == [256, 512]
        assert d["results"].shape == (2, 2)  # 2 evaluations x (2 seeds x 1 episode)
    assert vecnormalize_path_for(run / "checkpoints/ppo_256_steps.zip").is_file()


def test_new_run_refuses_a_finished_run_folder(pendulum_run: Path) -> None:
    with pytest.raises(ValueError, match="already holds a model.zip"):
        train(tiny(), run_dir=pendulum_run)


def test_resume_continues_timestep_counter(pendulum_run: Path, tmp_path: Path) -> None:
    import pickle

    from stable_baselines3 import PPO

    ckpt = pendulum_run / "checkpoints/ppo_256_steps.zip"
    run = train(tiny(total_timesteps=1024), run_dir=tmp_path / "resumed", resume=ckpt)
    assert PPO.load(run / "model.zip", device="cpu").num_timesteps == 1024
    assert (run / "checkpoints/ppo_1024_steps.zip").is_file()
    assert not (run / "checkpoints/ppo_256_steps.zip").exists()  # counter did not restart
    summary = json.loads((run / "train_summary.json").read_text())
    assert summary["start_timesteps"] == 256 and summary["resumed_from"] == str(ckpt)
    with open(vecnormalize_path_for(ckpt), "rb") as fh:
        n0 = pickle.load(fh).obs_rms.count
    with open(run / "vecnormalize.pkl", "rb") as fh:  # stats continued, not restarted
        n1 = pickle.load(fh).obs_rms.count
    assert n1 == pytest.approx(n0 + 1024 - 256 + 2)  # + the 2 first observations after reset
    with pytest.raises(ValueError, match="at 256 steps"):
        train(tiny(total_timesteps=256), run_dir=tmp_path / "again", resume=ckpt)
    with pytest.raises(ValueError, match="net_arch"):
        train(tiny(net_arch=[16]), run_dir=tmp_path / "arch", resume=ckpt)


def test_same_seed_same_parameters(tmp_path: Path) -> None:
    cfg = tiny(eval_freq=0, checkpoint_freq=0, seed=3)
    a = _params(train(cfg, run_dir=tmp_path / "a") / "model.zip")
    b = _params(train(cfg, run_dir=tmp_path / "b") / "model.zip")
    c = _params(train({**cfg, "seed": 4}, run_dir=tmp_path / "c") / "model.zip")
    assert a.keys() == b.keys()
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not all(np.array_equal(a[k], c[k]) for k in a)
    curve = [np.loadtxt(tmp_path / r / "monitor/0.monitor.csv", delimiter=",", skiprows=2,
                        usecols=0, ndmin=1) for r in ("a", "b")]
    assert np.array_equal(*curve) and curve[0].size >= 1


# ------------------------------------------------------------------------ policy, evaluate
def test_controller_actions_and_frozen_normalisation(tmp_path: Path) -> None:
    run = train(tiny(env_id=UNIT_PENDULUM, total_timesteps=256, eval_freq=0, checkpoint_freq=0),
                run_dir=tmp_path / "unit")
    ctrl = load_policy(run)
    assert isinstance(ctrl, PPOController) and ctrl.name == "PPO (unit)"
    vn = ctrl.vec_normalize
    mean, var = vn.obs_rms.mean.copy(), vn.obs_rms.var.copy()
    assert not np.allclose(var, 1.0)  # real statistics, not the identity
    ctrl.reset(seed=0)
    rng = np.random.default_rng(0)
    for obs in rng.uniform([-1, -1, -8], [1, 1, 8], size=(50, 3)).astype(np.float32):
        action = ctrl.act(obs)
        assert action.shape == (1,) and np.all(np.abs(action) <= 1.0)
        assert ctrl.info["inference_time_s"] > 0
        norm = np.clip((obs - mean) / np.sqrt(var + vn.epsilon), -vn.clip_obs, vn.clip_obs)
        expected, _ = ctrl.model.predict(norm.astype(np.float32), deterministic=True)
        np.testing.assert_allclose(action, expected, rtol=1e-6, atol=1e-7)
    assert np.array_equal(vn.obs_rms.mean, mean) and np.array_equal(vn.obs_rms.var, var)
    with pytest.raises(ValueError, match="observation shape"):
        ctrl.act(np.zeros(4))
    with pytest.raises(ValueError, match="no PPO policy"):
        load_policy(tmp_path / "nothing")


def test_evaluate_reproduces_training_evaluation(pendulum_run: Path) -> None:
    with np.load(pendulum_run / "eval/evaluations.npz") as d:
        best = d["results"].mean(axis=1).max()
    res = evaluate(pendulum_run / "eval/best", seeds=[7, 8], n_episodes=1)
    assert res["env_id"] == "Pendulum-v1" and res["n_episodes"] == 2
    assert res["mean_return"] == pytest.approx(best, abs=1e-4)  # Monitor rounds to 1e-6
    assert res["std_return"] >= 0 and res["lengths"] == [200, 200]
    res3 = evaluate(pendulum_run, env_id="Pendulum-v1", seeds=[1], n_episodes=2)
    assert len(res3["returns"]) == 2 and res3["returns"][0] != res3["returns"][1]


# ------------------------------------------------------------------------------------- CLI
def test_cli_train_missing_config_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    missing = tmp_path / "missing.yaml"
    assert main(["train", "ppo", "--config", str(missing)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(missing) in err and "not found" in err
    assert main(["train", "ppo", "--config", str(default_config_path("ppo_smoke.yaml")),
                 "--resume", str(tmp_path / "nope.zip")]) == 2
    assert "nope.zip" in capsys.readouterr().err


def test_eval_env_kwargs_that_cannot_make_an_env_are_named(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="eval_env_kwargs"):
        train(tiny(eval_env_kwargs={"no_such_pendulum_key": 1}), run_dir=tmp_path / "r")


def test_cli_train_bad_config_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("env_id: Pendulum-v1\nn_envs: zero\n")
    assert main(["train", "ppo", "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "'n_envs'" in err and str(bad) in err


def test_cli_train_smoke(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "cli_run"
    assert main(["train", "ppo", "--config", str(default_config_path("ppo_smoke.yaml")),
                 "--timesteps", "256", "--seed", "5", "--out", str(out)]) == 0
    assert str(out) in capsys.readouterr().out
    cfg = load_config(out / "config.yaml")
    assert cfg.total_timesteps == 256 and cfg.seed == 5
    assert (out / "model.zip").is_file() and (out / "vecnormalize.pkl").is_file()


def test_missing_optional_packages_give_notes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture) -> None:
    import dss14_env.agents.ppo

    monkeypatch.setattr(dss14_env.agents.ppo, "_installed", lambda *modules: False)
    run = train(tiny(total_timesteps=128, eval_freq=0, checkpoint_freq=0, progress_bar=True),
                run_dir=tmp_path / "bare")
    out = capsys.readouterr().out
    assert "tensorboard is not installed" in out and "no progress bar" in out
    assert (run / "model.zip").is_file() and not (run / "tb").exists()
