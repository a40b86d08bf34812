"""A newcomer's first commands: short budgets, a campaign folder as ``--ppo-model``, the
shipped configurations by kind, plurals (agents/train.py, agents/campaign.py, cli.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dss14_env.agents.campaign import best_seed_policy, is_campaign_folder
from dss14_env.agents.config import shipped_training_configs
from dss14_env.agents.train import train
from dss14_env.cli import main
from dss14_env.core.text import counted


def test_a_budget_below_eval_freq_still_writes_the_final_evaluation(tmp_path: Path) -> None:
    cfg = dict(env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=256, seed=0,
               n_steps=64, batch_size=64, n_epochs=1, net_arch=[16], eval_freq=10_240,
               n_eval_episodes=1, eval_seeds=[7], checkpoint_freq=0, progress_bar=False, verbose=0)
    run = train(cfg, run_dir=tmp_path / "run", progress=False)
    with np.load(run / "eval" / "evaluations.npz", allow_pickle=False) as d:
        assert d["timesteps"].tolist() == [256]
    assert (run / "eval" / "best" / "policy.pt").is_file()


def _fake_seed(folder: Path, k: int, scores: list[float]) -> None:
    best = folder / f"seed_{k}" / "eval" / "best"
    best.mkdir(parents=True)
    (best / "policy.pt").write_bytes(b"x")
    np.savez(best.parent / "evaluations.npz", timesteps=np.arange(len(scores)),
             selection_score=np.array(scores))


def test_a_campaign_folder_stands_for_its_best_validation_seed(tmp_path: Path) -> None:
    for k, scores in ((0, [-5.0, -3.0]), (1, [-4.0, -1.5]), (2, [-2.0])):
        _fake_seed(tmp_path, k, scores)
    assert is_campaign_folder(tmp_path) and not is_campaign_folder(tmp_path / "seed_1" / "eval" / "best")
    path, note = best_seed_policy(tmp_path)
    assert path == tmp_path / "seed_1" / "eval" / "best"
    assert "seed_1/eval/best" in note and "3 seeds" in note


def test_a_seed_that_beats_the_reference_ranks_before_a_better_score(tmp_path: Path) -> None:
    _fake_seed(tmp_path, 0, [-1.0, -0.9])
    _fake_seed(tmp_path, 1, [-3.0, -2.0])
    _fake_seed(tmp_path, 2, [-1.5])
    for k, ok in ((0, [False, False]), (1, [True, False]), (2, [False])):
        hist = tmp_path / f"seed_{k}" / "eval" / "evaluations.npz"
        with np.load(hist) as d:
            data = dict(d)
        np.savez(hist, **data, selection_qualified=np.array(ok))
    path, note = best_seed_policy(tmp_path)
    assert path == tmp_path / "seed_1" / "eval" / "best"
    assert "(-3)" in note and "beats the selection's reference" in note


def test_a_campaign_folder_without_results_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "seed_0").mkdir()
    with pytest.raises(ValueError, match="seed_0/eval/best"):
        best_seed_policy(tmp_path)


def test_train_help_lists_every_shipped_training_config(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for name in shipped_training_configs():
        assert f" {name}," in text or f" {name};" in text or f" {name})" in text


def test_train_config_error_lists_training_configs_only(capsys) -> None:
    assert main(["train", "ppo", "--config", "nope"]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and "ppo_plain" in err
    listed = err.split("configuration:")[-1]
    for other in ("controllers", "env,", "wind", " model"):
        assert other not in listed


def test_train_config_of_another_kind_is_named_as_such(capsys) -> None:
    assert main(["train", "ppo", "--config", "model"]) == 2
    err = capsys.readouterr().err
    assert "model.yaml: is a model configuration" in err and "like configs/ppo.yaml" in err


@pytest.mark.parametrize("n,word,out", [(0, "seed", "0 seeds"), (1, "chunk", "1 chunk"),
                                        (2, "run", "2 runs")])
def test_counted(n: int, word: str, out: str) -> None:
    assert counted(n, word) == out
