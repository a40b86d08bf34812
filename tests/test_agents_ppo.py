"""Training infrastructure (agents/config.py, agents/train.py, agents/policy.py, ``dss14 train``).

Everything runs on Gymnasium's Pendulum-v1 with a few hundred steps, so the whole file takes
seconds; the DSS14 paths are in test_agents_residual.py and test_agents_vec_env.py.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

from dss14_env.agents.config import (
    PPOConfig,
    TrainConfig,
    default_config_path,
    load_config,
)
from dss14_env.agents.policy import DEFAULT_POLICY, PolicyController, evaluate, load_policy
from dss14_env.agents.storage import load_stats, load_weights
from dss14_env.agents.train import RUN_FILES, train
from dss14_env.cli import main
from dss14_env.core.outdir import atomic_write_text, prepare_output_dir, update_manifest
from dss14_env.core.schema import ConfigError

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


def _params(run: Path) -> dict[str, np.ndarray]:
    _, state = load_weights(run / "policy.pt")
    return {k: v.numpy().copy() for k, v in state.items()}


@pytest.fixture(scope="module")
def pendulum_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return train(tiny(), run_dir=tmp_path_factory.mktemp("ppo") / "run")


# ---------------------------------------------------------------------------------- config
def test_shipped_configs_load_and_round_trip() -> None:
    cfg = load_config()
    assert cfg.algo == "ppo" and cfg.env_id == "DSS14-Residual-v0"
    assert load_config("ppo_plain").env_id == "DSS14-Plain-v0"  # shipped configs by name
    assert cfg.source == str(default_config_path())
    assert cfg.batch_size <= cfg.n_steps * cfg.n_envs
    assert load_config("ppo_smoke").env_id == "Pendulum-v1"
    assert load_config("sac").algo == "sac" and load_config("recurrent_ppo").algo == "recurrent_ppo"
    assert TrainConfig.from_dict(yaml.safe_load(yaml.safe_dump(cfg.to_dict()))) == cfg
    with pytest.raises(ConfigError, match="field 'learning_rate'"):  # a string is no number
        PPOConfig.from_dict({"learning_rate": "3e-4"})
    assert PPOConfig.from_dict({"total_timesteps": 1e6}).total_timesteps == 1_000_000
    # the shipped policy's run config still loads (written by the PPO-only version)
    assert load_config(DEFAULT_POLICY / "config.yaml").env_kwargs["history"] == 8


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
    ({"algo": "dqn"}, "algo"),
    ({"buffer_size": 1000}, "buffer_size"),        # a SAC key in a PPO config
    ({"algo": "sac", "ent_coef": "high"}, "ent_coef"),
    ({"algo": "sac", "net_arch": {"pi": [8], "vf": [8]}}, "net_arch"),
    ({"learning_rate": float("nan")}, "learning_rate"),
])
def test_config_errors_name_key_and_file(tmp_path: Path, bad: dict, key: str) -> None:
    path = tmp_path / "ppo_bad.yaml"
    path.write_text(yaml.safe_dump({"env_id": "Pendulum-v1", **bad}))
    with pytest.raises(ValueError, match=f"'{key}'") as err:
        load_config(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_config_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="missing.yaml: configuration file not found"):
        load_config(tmp_path / "missing.yaml")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="list.yaml: top level must be a mapping"):
        load_config(tmp_path / "list.yaml")
    (tmp_path / "broken.yaml").write_text("env_id: [Pendulum\n")
    with pytest.raises(ValueError, match=r"broken.yaml: not valid YAML \(line 2"):
        load_config(tmp_path / "broken.yaml")
    with pytest.raises(ValueError, match="field 'env_id': 'NoSuchEnv-v0' is not a registered"):
        train(tiny(env_id="NoSuchEnv-v0"), run_dir=tmp_path / "run")


# -------------------------------------------------------------------------------- training
def test_train_writes_every_output(pendulum_run: Path) -> None:
    run = pendulum_run
    for f in ("config.yaml", "policy.pt", "normalization.npz", "optimizer.pt", "counters.json",
              "train_summary.json", "checkpoints/256_steps/policy.pt",
              "checkpoints/256_steps/normalization.npz", "checkpoints/256_steps/optimizer.pt",
              "checkpoints/256_steps/counters.json", "checkpoints/256_steps/config.yaml",
              "checkpoints/512_steps/policy.pt", "eval/evaluations.npz", "eval/best/policy.pt",
              "eval/best/normalization.npz", "eval/best/config.yaml",
              "monitor/0.monitor.csv", "monitor/1.monitor.csv"):
        assert (run / f).is_file(), f
    assert not list(run.rglob("*.pkl")) and not list(run.rglob("*.zip"))  # nothing pickled
    assert any((run / "tb").rglob("events.out.tfevents.*"))  # tensorboard is in the dev venv
    assert load_config(run / "config.yaml") == TrainConfig.from_dict(tiny())
    summary = json.loads((run / "train_summary.json").read_text())
    assert summary["num_timesteps"] == 512 and summary["algo"] == "ppo"
    with np.load(run / "eval/evaluations.npz") as d:
        assert d["timesteps"].tolist() == [256, 512]
        assert d["results"].shape == (2, 2)  # 2 evaluations x (2 seeds x 1 episode)
    wfp, _ = load_weights(run / "policy.pt")
    sfp, _ = load_stats(run / "normalization.npz")
    assert wfp["run_id"] == sfp["run_id"] == summary["run_id"] and wfp["obs_dim"] == 3


def test_new_run_refuses_a_run_folder_unless_overwrite(pendulum_run: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(ValueError, match="already holds results .*--overwrite"):
        train(tiny(), run_dir=pendulum_run)
    # an interrupted run (config and a checkpoint, no final policy) is refused as well
    partial = tmp_path / "partial"
    prepare_output_dir(partial, RUN_FILES, command="train")  # the run claimed the folder ...
    (partial / "checkpoints" / "256_steps").mkdir(parents=True)
    atomic_write_text(partial / "config.yaml", "env_id: Pendulum-v1\n")
    update_manifest(partial)  # ... and was killed after its first checkpoint
    (partial / "notes.txt").write_text("mine")
    assert main(["train", "ppo", "--config", "ppo_smoke", "--out", str(partial)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--overwrite" in err
    run = train(tiny(total_timesteps=128, eval_freq=0, checkpoint_freq=0), run_dir=partial,
                overwrite=True)
    assert not (run / "checkpoints").exists()  # the old run's checkpoints are gone
    assert (run / "notes.txt").read_text() == "mine"  # what training does not own stays
    f = tmp_path / "a_file"
    f.write_text("x")
    assert main(["train", "ppo", "--config", "ppo_smoke", "--out", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "is a file" in err and str(f) in err


def test_resume_continues_timestep_counter(pendulum_run: Path, tmp_path: Path) -> None:
    ckpt = pendulum_run / "checkpoints/256_steps"
    run = train(tiny(total_timesteps=1024), run_dir=tmp_path / "resumed", resume=ckpt)
    counters = json.loads((run / "counters.json").read_text())
    assert counters["num_timesteps"] == 1024
    assert (run / "checkpoints/1024_steps").is_dir()
    assert not (run / "checkpoints/256_steps").exists()  # counter did not restart
    summary = json.loads((run / "train_summary.json").read_text())
    assert summary["start_timesteps"] == 256 and summary["resumed_from"] == str(ckpt)
    n0 = load_stats(ckpt / "normalization.npz")[1].obs_count
    n1 = load_stats(run / "normalization.npz")[1].obs_count
    assert n1 == pytest.approx(n0 + 1024 - 256 + 2)  # + the 2 first observations after reset
    assert summary["run_id"] == json.loads((ckpt / "counters.json").read_text())["run_id"]
    with pytest.raises(ValueError, match="at 256 steps"):
        train(tiny(total_timesteps=256), run_dir=tmp_path / "again", resume=ckpt)
    with pytest.raises(ValueError, match="net_arch"):
        train(tiny(net_arch=[16]), run_dir=tmp_path / "arch", resume=ckpt)
    with pytest.raises(ValueError, match="not a training checkpoint"):
        train(tiny(total_timesteps=1024), run_dir=tmp_path / "b", resume=pendulum_run / "eval/best")


def test_same_seed_same_parameters(tmp_path: Path) -> None:
    cfg = tiny(eval_freq=0, checkpoint_freq=0, seed=3)
    a = _params(train(cfg, run_dir=tmp_path / "a"))
    b = _params(train(cfg, run_dir=tmp_path / "b"))
    c = _params(train({**cfg, "seed": 4}, run_dir=tmp_path / "c"))
    assert a.keys() == b.keys()
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not all(np.array_equal(a[k], c[k]) for k in a)
    curve = [np.loadtxt(tmp_path / r / "monitor/0.monitor.csv", delimiter=",", skiprows=2,
                        usecols=0, ndmin=1) for r in ("a", "b")]
    assert np.array_equal(*curve) and curve[0].size >= 1


def test_ctrl_c_names_the_last_checkpoint_and_the_resume_command(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    from stable_baselines3.common.callbacks import BaseCallback

    import dss14_env.agents.train as T

    class Interrupt(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= 300:
                raise KeyboardInterrupt
            return True

    real = T._callbacks
    monkeypatch.setattr(T, "_callbacks", lambda *a: real(*a) + [Interrupt()])
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(tiny(total_timesteps=2048)))
    out = tmp_path / "run"
    assert main(["train", "ppo", "--config", str(cfg), "--out", str(out)]) == 130
    err = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress lines
    ckpt = out / "checkpoints" / "256_steps"
    assert str(ckpt) in err and "resume with: dss14 train ppo" in err
    command = err.split("resume with: ")[1].split()
    assert command[:3] == ["dss14", "train", "ppo"]
    monkeypatch.setattr(T, "_callbacks", real)
    assert main(command[1:]) == 0  # the printed command resumes and finishes the run
    assert json.loads((out / "counters.json").read_text())["num_timesteps"] == 2048


# ------------------------------------------------------------------------ policy, evaluate
def test_controller_actions_and_frozen_normalisation(tmp_path: Path) -> None:
    run = train(tiny(env_id=UNIT_PENDULUM, total_timesteps=256, eval_freq=0, checkpoint_freq=0),
                run_dir=tmp_path / "unit")
    ctrl = load_policy(run)
    assert isinstance(ctrl, PolicyController) and ctrl.name == "PPO (unit)"
    st = ctrl.stats
    mean, var = st.obs_mean.copy(), st.obs_var.copy()
    assert not np.allclose(var, 1.0)  # real statistics, not the identity
    ctrl.reset(seed=0)
    rng = np.random.default_rng(0)
    for obs in rng.uniform([-1, -1, -8], [1, 1, 8], size=(50, 3)).astype(np.float32):
        action = ctrl.act(obs)
        assert action.shape == (1,) and np.all(np.abs(action) <= 1.0)
        assert ctrl.info["inference_time_s"] > 0
        norm = np.clip((obs - mean) / np.sqrt(var + st.epsilon), -st.clip_obs, st.clip_obs)
        expected, _ = ctrl.policy.predict(norm.astype(np.float32), deterministic=True)
        np.testing.assert_allclose(action, expected, rtol=1e-6, atol=1e-7)
    assert np.array_equal(st.obs_mean, mean) and np.array_equal(st.obs_var, var)
    with pytest.raises(ValueError, match="observation shape"):
        ctrl.act(np.zeros(4))
    with pytest.raises(ValueError, match="non-finite"):
        ctrl.act(np.array([np.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match="no policy"):
        load_policy(tmp_path / "nothing")


def test_evaluate_reproduces_training_evaluation(pendulum_run: Path) -> None:
    with np.load(pendulum_run / "eval/evaluations.npz") as d:
        best = d["results"].mean(axis=1).max()
    res = evaluate(pendulum_run / "eval/best", seeds=[7, 8], n_episodes=1)
    assert res["env_id"] == "Pendulum-v1" and res["n_episodes"] == 2
    assert res["mean_return"] == pytest.approx(best, rel=1e-9)
    assert res["std_return"] >= 0 and res["lengths"] == [200, 200]
    res3 = evaluate(pendulum_run, env_id="Pendulum-v1", seeds=[1], n_episodes=2)
    assert len(res3["returns"]) == 2 and res3["returns"][0] != res3["returns"][1]


# ------------------------------------------------------------------------------------- CLI
def test_cli_train_missing_config_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    missing = tmp_path / "missing.yaml"
    assert main(["train", "ppo", "--config", str(missing)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(missing) in err and "not found" in err
    assert main(["train", "ppo", "--config", "ppo_smoke", "--resume", str(tmp_path / "nope")]) == 2
    assert "nope" in capsys.readouterr().err
    assert main(["train", "sac", "--config", "ppo_smoke"]) == 2
    assert "'algo'" in capsys.readouterr().err


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
    assert main(["train", "ppo", "--config", "ppo_smoke", "--timesteps", "256", "--seed", "5",
                 "--out", str(out)]) == 0
    assert str(out) in capsys.readouterr().out
    cfg = load_config(out / "config.yaml")
    assert cfg.total_timesteps == 256 and cfg.seed == 5
    assert (out / "policy.pt").is_file() and (out / "normalization.npz").is_file()


def test_missing_tensorboard_gives_a_note(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture) -> None:
    import dss14_env.agents.train

    monkeypatch.setattr(dss14_env.agents.train, "_installed", lambda *modules: False)
    run = train(tiny(total_timesteps=128, eval_freq=0, checkpoint_freq=0, progress_bar=True),
                run_dir=tmp_path / "bare")
    out = capsys.readouterr()
    assert "tensorboard is not installed" in out.out
    assert "128/128 steps (100 %) done" in out.err  # the progress needs no optional package
    assert (run / "policy.pt").is_file() and not (run / "tb").exists()
