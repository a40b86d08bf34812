"""Every algorithm of ``dss14 train`` (PPO, RecurrentPPO, SAC) on DSS14 environments: a tiny
training with evaluation and checkpoints, the policy loaded back, resumed from a checkpoint;
many-seed campaigns (agents/campaign.py); rl-zoo3-format hyperparameters."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from dss14_env.agents.campaign import parse_seeds, train_seeds
from dss14_env.agents.config import TrainConfig
from dss14_env.agents.hyperparams import hyperparams_path, load_hyperparams, parse_zoo_value
from dss14_env.agents.policy import load_policy
from dss14_env.agents.train import train
from dss14_env.cli import main

COMMON = dict(n_envs=2, eval_freq=200, eval_seeds=[1000], eval_episode_steps=260,
              checkpoint_freq=200, progress_bar=False, verbose=0)
RUNS = {
    "ppo_frame_stack": dict(algo="ppo", env_id="DSS14-Hold-v0", frame_stack=2,
                            env_kwargs={"max_episode_steps": 100}, total_timesteps=400,
                            n_steps=100, batch_size=100, n_epochs=1, net_arch=[16]),
    "recurrent_ppo": dict(algo="recurrent_ppo", env_id="DSS14-Residual-v0",
                          env_kwargs={"max_episode_steps": 100}, total_timesteps=400,
                          n_steps=100, batch_size=100, n_epochs=1, net_arch=[16],
                          lstm_hidden_size=8),
    "sac": dict(algo="sac", env_id="DSS14-Hold-v0", env_kwargs={"max_episode_steps": 100},
                total_timesteps=400, learning_starts=100, buffer_size=1000, batch_size=32,
                net_arch=[16, 16]),
}


@pytest.mark.parametrize("name", sorted(RUNS))
def test_train_load_resume(name: str, tmp_path: Path) -> None:
    cfg = {**COMMON, **RUNS[name]}
    run = train(cfg, run_dir=tmp_path / "run")
    for f in ("policy.pt", "normalization.npz", "config.yaml", "optimizer.pt",
              "checkpoints/200_steps/counters.json", "eval/best/policy.pt"):
        assert (run / f).is_file(), f
    if cfg["algo"] == "sac":
        assert (run / "checkpoints/200_steps/replay_buffer.npz").is_file()
    with np.load(run / "eval/evaluations.npz") as d:
        assert d["timesteps"].tolist() == [200, 400]
        assert np.all(np.isfinite(d["three_sigma_mdeg_hold_side"]))
    for folder in (run, run / "eval/best", run / "checkpoints/200_steps"):
        ctrl = load_policy(folder)
        ctrl.reset()
        assert ctrl.act(np.zeros(12, np.float32)).shape == (2,)
    resumed = train({**cfg, "total_timesteps": 600}, run_dir=tmp_path / "more",
                    resume=run / "checkpoints/200_steps")
    assert json.loads((resumed / "counters.json").read_text())["num_timesteps"] == 600


def test_seed_protocol_is_enforced_for_dss14(tmp_path: Path) -> None:
    base = {**COMMON, **RUNS["ppo_frame_stack"]}
    with pytest.raises(ValueError, match="'seed': DSS14 training seeds start at 10000"):
        train({**base, "seed": 5}, run_dir=tmp_path / "a")
    with pytest.raises(ValueError, match="'eval_seeds': validation seeds are 1000-9999"):
        train({**base, "eval_seeds": [3]}, run_dir=tmp_path / "b")
    with pytest.raises(ValueError, match="'frame_stack'"):
        train({**base, "env_id": "DSS14-Residual-v0"}, run_dir=tmp_path / "c")
    with pytest.raises(ValueError, match="'eval_episode_steps': .*warm-up"):
        train({**base, "eval_episode_steps": 100}, run_dir=tmp_path / "d")


@pytest.mark.parametrize("values, seeds", [(["0-4"], [0, 1, 2, 3, 4]), (["0", "3", "7"], [0, 3, 7]),
                                           (["2"], [2])])
def test_parse_seeds(values: list[str], seeds: list[int]) -> None:
    assert parse_seeds(values) == seeds


@pytest.mark.parametrize("values", [["4-1"], ["a"], ["1", "1"], []])
def test_parse_seeds_errors(values: list[str]) -> None:
    with pytest.raises(ValueError, match="--train-seeds"):
        parse_seeds(values)


def test_campaign_same_seed_same_result_pendulum(tmp_path: Path) -> None:
    cfg = dict(env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=128, seed=0,
               n_steps=64, batch_size=64, n_epochs=1, net_arch=[8], eval_freq=64,
               eval_seeds=[7], checkpoint_freq=0, progress_bar=False, verbose=0)
    runs = [json.loads((train_seeds(cfg, [0, 1], tmp_path / d, test_seeds=(0, 1)) / "summary.json")
                       .read_text()) for d in ("a", "b")]
    for s in runs:
        for e in s["per_seed"]:
            e.pop("wall_s")
    assert runs[0]["per_seed"] == runs[1]["per_seed"] and runs[0]["aggregate"] == runs[1]["aggregate"]
    assert runs[0]["training_seeds"] == [0, 1000]
    agg = runs[0]["aggregate"]["best"]["eval"]
    assert agg["metric"] == "mean_return" and agg["per_seed"][0] != agg["per_seed"][1]
    assert (tmp_path / "a" / "curves_eval.png").is_file()


@pytest.mark.slow
def test_campaign_same_seed_same_result(tmp_path: Path) -> None:
    cfg = {**COMMON, **RUNS["ppo_frame_stack"], "checkpoint_freq": 0, "total_timesteps": 200,
           "eval_freq": 100}
    kw = dict(test_seeds=(0, 1), test_steps=260)
    a = train_seeds(cfg, [0, 1], tmp_path / "a", **kw)
    b = train_seeds(cfg, [0, 1], tmp_path / "b", **kw)
    sa = json.loads((a / "summary.json").read_text())
    sb = json.loads((b / "summary.json").read_text())
    for s in (sa, sb):
        for e in s["per_seed"]:
            e.pop("wall_s")
            e["run"] = None
    assert sa["per_seed"] == sb["per_seed"] and sa["aggregate"] == sb["aggregate"]
    assert sa["training_seeds"] == [10000, 11000]
    first = sa["per_seed"][0]
    assert first["env_steps"] == 200 and len(first["final"]["hold_front"]["three_sigma_mdeg"]) == 2
    agg = sa["aggregate"]["final"]["hold_side"]
    assert agg["metric"] == "mean_three_sigma_mdeg" and len(agg["per_seed"]) == 2
    lo, hi = agg["iqm"]["ci95"]
    assert lo <= agg["iqm"]["value"] <= hi
    assert (a / "curves_hold_front.png").is_file() and (a / "curves_hold_side.png").is_file()
    # a different seed index gives a different run
    c = train_seeds({**cfg, "eval_freq": 0}, [2], tmp_path / "c", figures=False, **kw)
    sc = json.loads((c / "summary.json").read_text())
    assert sc["per_seed"][0]["final"] != sa["per_seed"][0]["final"]
    with pytest.raises(ValueError, match="--overwrite"):
        train_seeds(cfg, [0], tmp_path / "a", **kw)


def test_cli_seeds(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({**COMMON, **RUNS["ppo_frame_stack"], "checkpoint_freq": 0,
                                   "eval_freq": 0}))
    assert main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0", "--seed", "10000",
                 "--out", str(tmp_path / "x")]) == 2
    assert "--train-seeds" in capsys.readouterr().err


def test_shipped_hyperparameters_load_for_every_entry() -> None:
    for algo in ("ppo", "recurrent_ppo", "sac"):
        data = yaml.safe_load(hyperparams_path(algo).read_text())
        for env_id in data:
            cfg = load_hyperparams(algo, env_id)
            assert isinstance(cfg, TrainConfig) and cfg.algo == algo and cfg.env_id == env_id
    with pytest.raises(ValueError, match="no hyperparameters for 'Nope-v0'"):
        load_hyperparams("ppo", "Nope-v0")


def test_zoo_strings_are_parsed_not_evaluated() -> None:
    v = parse_zoo_value("dict(net_arch=[64, 64], activation_fn=nn.ReLU, log_std_init=-2)", "f")
    assert v == {"net_arch": [64, 64], "activation_fn": "relu", "log_std_init": -2}
    with pytest.raises(ValueError, match="nothing is evaluated"):
        parse_zoo_value("dict(x=__import__('os').system('true'))", "f")


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ["DSS14-Hold-v0", "DSS14-Plain-v0"])
def test_rl_zoo3_trains_with_the_shipped_hyperparameters(tmp_path: Path, env_id: str) -> None:
    """rl-zoo3 reads configs/hyperparams/ppo.yml and trains on the bare id and on the plain
    recipe's id (tiny budget)."""
    import subprocess
    import sys

    pytest.importorskip("rl_zoo3")
    res = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", env_id,
         "--gym-packages", "dss14_env", "-conf", str(hyperparams_path("ppo")), "-n", "1024",
         "--eval-freq", "-1", "--log-folder", str(tmp_path), "--seed", "10000",
         "--hyperparams", "n_envs:2", "n_steps:256", "batch_size:256", "n_epochs:1"],
        capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    assert list(tmp_path.rglob(f"{env_id}.zip"))


def test_interrupted_campaign_continues(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    cfg = {**COMMON, **RUNS["ppo_frame_stack"], "checkpoint_freq": 0, "total_timesteps": 200,
           "eval_freq": 0}
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(cfg))
    kw = dict(test_seeds=(0,), test_steps=260, figures=False)
    out = tmp_path / "cut"
    whole = json.loads((train_seeds(str(path), [0, 1], out, **kw) / "summary.json").read_text())
    # interrupted: seed 1 stopped before its last file, the summary never written
    (out / "seed_1" / "train_summary.json").unlink()
    (out / "summary.json").unlink()
    kept = (out / "seed_0" / "policy.pt").stat().st_mtime_ns
    with pytest.raises(ValueError, match="--overwrite"):
        train_seeds(str(path), [0, 1], out, **kw)
    train_seeds(str(path), [0, 1], out, resume=True, **kw)
    assert (out / "seed_0" / "policy.pt").stat().st_mtime_ns == kept  # scored, not retrained
    cont = json.loads((out / "summary.json").read_text())
    for s in (whole, cont):
        for e in s["per_seed"]:
            e.pop("wall_s")
    assert cont["per_seed"] == whole["per_seed"] and cont["aggregate"] == whole["aggregate"]
    # another configuration is refused, naming the campaign's file
    other = tmp_path / "other.yaml"
    other.write_text(yaml.safe_dump({**cfg, "total_timesteps": 400}))
    with pytest.raises(ValueError, match="config.yaml is another configuration"):
        train_seeds(str(other), [0, 1], out, resume=True, **kw)
    assert main(["train", "ppo", "--config", str(path), "--train-seeds", "0", "--resume",
                 "--overwrite", "--out", str(out)]) == 2
    assert "--resume keeps the finished runs" in capsys.readouterr().err
    assert main(["train", "ppo", "--config", str(path), "--train-seeds", "0", "--resume",
                 "--out", str(tmp_path / "empty")]) == 2
    assert "no campaign to continue" in capsys.readouterr().err


def test_a_campaign_with_a_bad_environment_fails_before_any_work(tmp_path: Path) -> None:
    cfg = {**COMMON, **RUNS["ppo_frame_stack"], "env_kwargs": {"max_episode_steps": 100,
                                                               "wind_speed_kmh": "gale"}}
    with pytest.raises(ValueError, match=r"wind_speed_kmh"):
        train_seeds(cfg, [0, 1], tmp_path / "c")
    assert not (tmp_path / "c").exists()
