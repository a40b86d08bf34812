"""Files and options from elsewhere: nothing they say is imported or run, nothing of the user's is
deleted, no failed resume loses a checkpoint, and every bad value is one line before any work.

Each test re-creates a hostile input (a policy folder naming a module of its own, a YAML alias
bomb, a truncated checkpoint, a cluster address nobody answers, ...) and checks the refusal or
the intact files.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from pathlib import Path

import pytest
import yaml

from dss14_env import cli
from dss14_env.agents.config import MAX_SEED, load_config
from dss14_env.agents.policy import DEFAULT_POLICY, dss14_policy_problem, load_policy, shipped_policy
from dss14_env.agents.train import TrainingInterrupted, train
from dss14_env.core.folderlock import LOCK_FILE
from dss14_env.core.outdir import (
    MANIFEST,
    OutputDirError,
    atomic_folder,
    atomic_write_text,
    prepare_output_dir,
    remove_run_files,
    update_manifest,
)
from dss14_env.core.parallel import probe_address, split_address
from dss14_env.core.schema import MAX_CONFIG_BYTES, ConfigError, UniqueKeySafeLoader, read_config

#: a training run of a second or two (Pendulum: no DSS14 model to build), two checkpoints
TINY = dict(algo="ppo", env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=256,
            seed=0, n_steps=64, batch_size=64, n_epochs=1, net_arch=[8], eval_freq=0,
            eval_seeds=[7], checkpoint_freq=128, progress_bar=False, verbose=0)


def _write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _one_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


# ------------------------------------------------------------------ nothing imported from a file
@pytest.fixture
def payload(tmp_path: Path, monkeypatch) -> tuple[str, Path]:
    """An importable module that leaves a marker file when imported (code a folder ships)."""
    marker = tmp_path / "marker"
    pkg = tmp_path / "shipped_code"
    pkg.mkdir()
    name = f"payload_{tmp_path.name.replace('-', '_')}"
    (pkg / f"{name}.py").write_text(f"import pathlib\npathlib.Path({str(marker)!r}).write_text('ran')\n")
    monkeypatch.syspath_prepend(str(pkg))
    return name, marker


def _evil_policy(tmp_path: Path, **changes) -> Path:
    folder = tmp_path / "evil"
    shutil.copytree(shipped_policy("ppo_plain"), folder)
    cfg = yaml.safe_load((folder / "config.yaml").read_text())
    cfg.update(changes)
    _write(folder / "config.yaml", cfg)
    return folder


def test_a_policy_folder_cannot_make_load_policy_import_its_module(payload, tmp_path: Path) -> None:
    name, marker = payload
    folder = _evil_policy(tmp_path, env_module=name)
    with pytest.raises(ConfigError, match=rf"config.yaml: field 'env_module': '{name}' names a module"):
        load_policy(folder)
    assert not marker.exists()
    # the user's explicit opt-in loads it (the file may then name that module)
    assert load_config(folder / "config.yaml", env_module=name).env_module == name


@pytest.mark.parametrize("changes, field", [
    ({"env_module": "this"}, "env_module"),
    ({"env_module": "os"}, "env_module"),
    ({"env_id": "shipped_code_x:Evil-v0"}, "env_id"),
    ({"env_kwargs": {"base_id": "shipped_code_x:Evil-v0"}}, "env_kwargs.base_id"),
])
def test_no_config_field_names_a_module_to_import(tmp_path: Path, changes: dict, field: str) -> None:
    path = _write(tmp_path / "c.yaml", {**TINY, **changes})
    with pytest.raises(ConfigError, match=rf"^{path}: field '{field}': "):
        load_config(path)


def test_a_sweep_cannot_name_a_module_either(tmp_path: Path) -> None:
    path = _write(tmp_path / "s.yaml", {**TINY, "sweep": {"env_module": [None, "this"]}})
    with pytest.raises(ConfigError, match="field 'env_module': 'this' names a module"):
        load_config(path)


def test_env_module_on_the_command_line_is_the_users_opt_in(tmp_path: Path, monkeypatch,
                                                            capsys) -> None:
    pkg = tmp_path / "mine"
    pkg.mkdir()
    name = f"myenvs_{tmp_path.name.replace('-', '_')}"
    env_id = f"Mine{abs(hash(name)) % 10**6}-v0"
    (pkg / f"{name}.py").write_text(
        "import gymnasium as gym\n"
        f"gym.register({env_id!r}, entry_point='gymnasium.envs.classic_control:PendulumEnv', "
        "max_episode_steps=200)\n")
    monkeypatch.syspath_prepend(str(pkg))
    cfg = _write(tmp_path / "c.yaml", {**TINY, "env_id": env_id, "env_module": name,
                                       "checkpoint_freq": 0})
    out = tmp_path / "run"
    assert cli.main(["train", "ppo", "--config", str(cfg), "--out", str(out)]) == 2
    _one_line(capsys, "field 'env_module'", f"--env-module {name}")
    assert not out.exists() and name not in sys.modules
    assert cli.main(["train", "ppo", "--config", str(cfg), "--out", str(out),
                     "--env-module", name]) == 0
    assert yaml.safe_load((out / "config.yaml").read_text())["env_module"] == name
    with pytest.raises(ConfigError, match="field 'env_module'"):  # loading it needs the opt-in too
        load_policy(out)
    assert load_policy(out, env_module=name).config.env_id == env_id


def test_an_unregistered_env_id_is_named_with_the_opt_in(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"field 'env_id': 'Nowhere-v9' is not a registered .*--env-module"):
        train({**TINY, "env_id": "Nowhere-v9"}, run_dir=tmp_path / "r")
    assert not (tmp_path / "r").exists()


def test_bench_refuses_the_policy_folder_before_any_work(payload, tmp_path: Path, capsys) -> None:
    name, marker = payload
    folder = _evil_policy(tmp_path, env_module=name)
    out = tmp_path / "o1"
    assert cli.main(["bench", "--ppo-model", str(folder), "--controllers", "ppo", "--scenarios",
                     "hold_front", "--no-sweep", "--episodes", "2", "--steps", "300",
                     "--out", str(out)]) == 2
    _one_line(capsys, "--ppo-model", "env_module")
    assert not marker.exists() and not out.exists()


# ------------------------------------------------------------------ policies that cannot act
def test_a_policy_of_another_environment_is_refused_before_work(tmp_path: Path, capsys) -> None:
    run = train({**TINY, "checkpoint_freq": 0}, run_dir=tmp_path / "pendulum")
    problem = dss14_policy_problem(run)
    assert problem is not None and "3 observations" in problem and "12" in problem
    assert dss14_policy_problem(DEFAULT_POLICY) is None
    out = tmp_path / "b"
    assert cli.main(["bench", "--ppo-model", str(run), "--controllers", "ppo", "--scenarios",
                     "hold_front", "--no-sweep", "--out", str(out)]) == 2
    _one_line(capsys, "--ppo-model", "3 observations")
    assert not out.exists()


def test_campaign_refuses_a_missing_policy_before_the_folder(tmp_path: Path, capsys) -> None:
    out = tmp_path / "c"
    assert cli.main(["campaign", "--plants", "1", "--steps", "300", "--controllers", "ppo",
                     "--ppo-model", str(tmp_path / "nonexistent"), "--out", str(out)]) == 2
    _one_line(capsys, "--ppo-model", "nonexistent")
    assert not out.exists()


def test_an_empty_policy_config_is_refused_at_load(tmp_path: Path) -> None:
    folder = tmp_path / "p"
    shutil.copytree(shipped_policy("ppo_plain"), folder)
    (folder / "config.yaml").write_text("")
    with pytest.raises(ValueError, match="config.yaml"):
        load_policy(folder)


# ------------------------------------------------------------------ the user's files survive
def test_overwrite_removes_only_what_a_manifest_lists(tmp_path: Path) -> None:
    out = tmp_path / "out"
    owned = ("results.json", "chunks", "*.png")
    prepare_output_dir(out, owned, command="bench")
    (out / "chunks").mkdir()
    for f in ("results.json", "chunks/c0.json", "fig.png"):
        atomic_write_text(out / f, "run")
    assert update_manifest(out) == ["chunks/c0.json", "fig.png", "results.json"]
    (out / "holiday.png").write_text("mine")  # the user's, written after the run
    (out / "notes.txt").write_text("mine")
    with pytest.raises(OutputDirError, match=r"already holds results \(chunks, fig.png, results.json\)"):
        prepare_output_dir(out, owned, command="bench")
    prepare_output_dir(out, owned, overwrite=True, command="bench")
    assert sorted(p.name for p in out.iterdir() if p.name != LOCK_FILE) == [
        MANIFEST, "holiday.png", "notes.txt"]


@pytest.mark.parametrize("user_file", ["results.json", "chunks/mine.json"])
def test_a_user_file_where_the_run_writes_is_refused_not_removed(tmp_path: Path, user_file) -> None:
    out = tmp_path / "out"
    owned = ("results.json", "chunks", "*.png")
    prepare_output_dir(out, owned, command="bench")
    atomic_write_text(out / "fig.png", "run")
    update_manifest(out)
    (out / "chunks").mkdir(exist_ok=True)
    (out / user_file).write_text("mine")
    for overwrite in (False, True):
        with pytest.raises(OutputDirError, match=rf"no run's manifest .* lists .*{user_file}"):
            prepare_output_dir(out, owned, overwrite=overwrite, command="bench")
    assert (out / user_file).read_text() == "mine" and (out / "fig.png").read_text() == "run"


def test_a_folder_of_an_earlier_version_is_never_emptied(tmp_path: Path) -> None:
    (tmp_path / "metrics.json").write_text("{}")  # results without a manifest
    with pytest.raises(OutputDirError, match="metrics.json"):
        prepare_output_dir(tmp_path, ("metrics.json",), overwrite=True, command="reproduce")
    assert (tmp_path / "metrics.json").read_text() == "{}"


def test_dry_run_and_remove_run_files_touch_only_listed_files(tmp_path: Path) -> None:
    prepare_output_dir(tmp_path, ("summary.json", "curves_*.png"), command="train --seeds")
    atomic_write_text(tmp_path / "summary.json", "{}")
    update_manifest(tmp_path)
    (tmp_path / "curves_mine.png").write_text("mine")
    prepare_output_dir(tmp_path, ("summary.json",), overwrite=True, dry_run=True, command="train --seeds")
    assert (tmp_path / "summary.json").is_file()
    assert remove_run_files(tmp_path, ("summary.json", "curves_*.png")) == ["summary.json"]
    assert (tmp_path / "curves_mine.png").read_text() == "mine"


def test_reproduce_overwrite_keeps_the_users_pngs(tmp_path: Path, monkeypatch) -> None:
    from dss14_env import reproduce as R

    def fake(out, model, figures=True, progress=False):  # the real run takes minutes; its files matter
        atomic_write_text(Path(out, "metrics.json"), "{}")
        atomic_write_text(Path(out, "metrics.md"), "")
        atomic_write_text(Path(out, "fig01.png"), "png")
        return {"markdown": "", "table": "", "figures": ["fig01.png"], "failed": [], "metrics": {}}

    monkeypatch.setattr(R, "reproduce", fake)
    monkeypatch.setattr("dss14_env.model.assembly.default_model", lambda: None)
    out = tmp_path / "rp"
    out.mkdir()
    (out / "holiday.png").write_bytes(b"mine")
    assert cli.main(["reproduce", "--out", str(out)]) == 0
    (out / "later.png").write_bytes(b"mine too")
    assert cli.main(["reproduce", "--out", str(out), "--overwrite"]) == 0
    assert (out / "holiday.png").read_bytes() == b"mine" and (out / "later.png").read_bytes() == b"mine too"
    assert json.loads((out / MANIFEST).read_text())["files"] == ["fig01.png", "metrics.json", "metrics.md"]


def test_atomic_folder_is_all_or_nothing(tmp_path: Path) -> None:
    target = tmp_path / "ckpt"
    with pytest.raises(RuntimeError), atomic_folder(target) as tmp:
        (tmp / "policy.pt").write_text("half")
        raise RuntimeError("killed")
    assert not target.exists() and list(tmp_path.iterdir()) == []
    with atomic_folder(target) as tmp:
        (tmp / "policy.pt").write_text("v1")
        (tmp / "config.yaml").write_text("v1")
    with atomic_folder(target) as tmp:
        (tmp / "policy.pt").write_text("v2")
    assert sorted(p.name for p in target.iterdir()) == ["policy.pt"]
    assert [p.name for p in tmp_path.iterdir()] == ["ckpt"]


# ------------------------------------------------------------------ resuming
@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    return train(TINY, run_dir=tmp_path_factory.mktemp("tiny") / "run")


def test_a_failed_resume_keeps_every_checkpoint(tiny_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    before = sorted(p.name for p in (run / "checkpoints").iterdir())
    assert before == ["128_steps", "256_steps"]
    opt = run / "checkpoints" / "128_steps" / "optimizer.pt"
    opt.write_bytes(opt.read_bytes()[:300])
    with pytest.raises(ValueError, match="optimizer.pt"):
        train(run / "config.yaml", resume=run / "checkpoints" / "128_steps")
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == before


def test_resume_refuses_another_runs_normalisation(tiny_run: Path, tmp_path: Path) -> None:
    other = train({**TINY, "seed": 5, "checkpoint_freq": 0}, run_dir=tmp_path / "other")
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    ckpt = run / "checkpoints" / "128_steps"
    shutil.copy(other / "normalization.npz", ckpt / "normalization.npz")
    with pytest.raises(ValueError, match=r"normalization.npz: belongs to another run"):
        train(run / "config.yaml", resume=ckpt)
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["128_steps", "256_steps"]


@pytest.mark.parametrize("changes,field", [
    ({"num_timesteps": -5}, "num_timesteps"),
    ({"num_timesteps": 0}, "num_timesteps"),
    ({"num_timesteps": "128"}, "num_timesteps"),
    ({"num_timesteps": 128.5}, "num_timesteps"),
    ({"num_timesteps": True}, "num_timesteps"),
    ({"num_timesteps": 10**13}, "num_timesteps"),
    ({"num_timesteps": 256}, "num_timesteps"),  # the next checkpoint's count: two branches mixed
    ({"episode_num": -1}, "episode_num"),
    ({"run_id": "../../x"}, "run_id"),
    ({"run_id": 7}, "run_id"),
])
def test_every_number_of_a_checkpoints_counters_is_checked(tiny_run: Path, tmp_path: Path,
                                                           changes: dict, field: str) -> None:
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    ckpt = run / "checkpoints" / "128_steps"
    counters = json.loads((ckpt / "counters.json").read_text())
    (ckpt / "counters.json").write_text(json.dumps({**counters, **changes}))
    with pytest.raises(ValueError, match=rf"128_steps/counters.json: field '{field}'"):
        train(run / "config.yaml", resume=ckpt)
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["128_steps", "256_steps"]


def test_a_huge_counters_file_is_refused_unread(tiny_run: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    ckpt = run / "checkpoints" / "128_steps"
    (ckpt / "counters.json").write_text(" " * 10**6 + "{}")
    with pytest.raises(ValueError, match=r"counters.json: not a readable counters file \(more than"):
        train(run / "config.yaml", resume=ckpt)


def test_resume_without_a_checkpoint_takes_the_runs_last(tiny_run: Path, tmp_path: Path,
                                                         capsys) -> None:
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    cfg = _write(tmp_path / "more.yaml", {**TINY, "total_timesteps": 384})
    assert cli.main(["train", "ppo", "--config", str(cfg), "--out", str(run), "--resume"]) == 0
    summary = json.loads((run / "train_summary.json").read_text())
    assert summary["resumed_from"].endswith("256_steps") and summary["num_timesteps"] >= 384


def test_interrupted_before_a_checkpoint_says_the_command(tmp_path: Path, monkeypatch) -> None:
    import stable_baselines3

    def stop(self, *a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(stable_baselines3.PPO, "learn", stop)
    with pytest.raises(TrainingInterrupted) as info:
        train({**TINY, "checkpoint_freq": 0}, run_dir=tmp_path / "r")
    cmd = info.value.command
    assert cmd.startswith("dss14 train ppo --config ") and cmd.endswith(f"--overwrite --out {tmp_path / 'r'}")


def test_a_seeds_campaign_interrupted_gives_the_campaign_command(tmp_path: Path, monkeypatch,
                                                                  capsys) -> None:
    from dss14_env.agents import campaign

    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(campaign, "train", stop)
    cfg = _write(tmp_path / "c.yaml", {**TINY, "checkpoint_freq": 0, "eval_freq": 64})
    out = tmp_path / "camp"
    assert cli.main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0-1", "--out", str(out)]) == 130
    err = capsys.readouterr().err.strip().splitlines()[-1]  # after the campaign's plan line
    want = f"dss14 train ppo --config {out / 'config.yaml'} --train-seeds 0-1 --out {out} --resume"
    assert err.endswith(want)
    monkeypatch.undo()
    # the command given continues the campaign
    args = want.split()[1:]
    assert cli.main(args) == 0
    assert json.loads((out / "summary.json").read_text())["seed_indices"] == [0, 1]


def test_an_interrupted_campaign_gives_its_command(tmp_path: Path, monkeypatch, capsys) -> None:
    from dss14_env.bench import campaign as C

    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(C, "run_chunks", stop)
    out = tmp_path / "c"
    argv = ["campaign", "--plants", "1", "--steps", "300", "--controllers", "pi_kp1", "--out", str(out)]
    assert cli.main([*argv, "--overwrite"]) == 130
    err = _one_line(capsys, "continue with:")
    assert err.endswith("continue with: dss14 " + " ".join(argv) + " --resume")


def test_an_interrupted_bench_gives_the_command_that_starts_it_again(tmp_path: Path, monkeypatch,
                                                                     capsys) -> None:
    from dss14_env.bench import bench as B

    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(B, "run_plan", stop)
    argv = ["bench", "--controllers", "pi_kp1", "--scenarios", "step", "--out", str(tmp_path / "b")]
    assert cli.main(argv) == 130
    err = _one_line(capsys, "stopped (SIGINT)")
    assert err.endswith("start again with: dss14 " + " ".join(argv) + " --overwrite")


def test_resume_continues_a_campaign_and_continue_names_it(tmp_path: Path, capsys) -> None:
    cfg = _write(tmp_path / "c.yaml", {**TINY, "checkpoint_freq": 0, "eval_freq": 64,
                                       "total_timesteps": 128})
    out = tmp_path / "camp"
    assert cli.main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0", "--out", str(out)]) == 0
    kept = (out / "seed_0" / "policy.pt").stat().st_mtime_ns
    assert cli.main(["train", "ppo", "--config", str(cfg), "--train-seeds", "0", "--out", str(out),
                     "--resume"]) == 0
    assert (out / "seed_0" / "policy.pt").stat().st_mtime_ns == kept  # scored, not retrained
    capsys.readouterr()
    for old, new in ((["--continue"], "--resume"), (["--seeds", "0"], "--train-seeds")):
        assert cli.main(["train", "ppo", "--config", str(cfg), "--out", str(out), *old]) == 2
        _one_line(capsys, f"{old[0]}: is now {new}")
    assert cli.main(["campaign", "--out", str(tmp_path / "c"), "--continue"]) == 2
    _one_line(capsys, "--continue: is now --resume")


# ------------------------------------------------------------------ YAML and numbers
def test_an_alias_bomb_is_refused_at_once(tmp_path: Path, monkeypatch) -> None:
    """Refused on the node graph, before any Python object of the document is built."""
    lines = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 10)]
    lines += ["net_arch: *a9"]
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(lines) + "\n")

    def built(*_: object) -> None:
        raise AssertionError("the document was built before its size was checked")

    monkeypatch.setattr(UniqueKeySafeLoader, "construct_document", built)
    with pytest.raises(ConfigError, match=rf"^{path}: the YAML expands to more than"):
        load_config(path)


def test_long_and_deep_files_are_refused_naming_the_file(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    big.write_text("x: 1\n" * (MAX_CONFIG_BYTES // 5 + 1))
    with pytest.raises(ConfigError, match=rf"^{big}: longer than"):
        read_config(big)
    deep = tmp_path / "deep.yaml"
    deep.write_text("x: " + "[" * 20000 + "]" * 20000 + "\n")
    with pytest.raises(ConfigError, match=rf"^{deep}: "):
        read_config(deep)


def test_scientific_notation_is_a_number_and_quoted_numbers_are_strings(tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text("learning_rate: 1e-3\ntotal_timesteps: 1.28e2\nenv_id: Pendulum-v1\n"
                    "n_envs: 2\nbatch_size: 64\nn_steps: 64\n")
    cfg = load_config(path)
    assert cfg.learning_rate == 1e-3 and cfg.total_timesteps == 128
    path.write_text("env_id: Pendulum-v1\nn_steps: '256'\n")
    with pytest.raises(ConfigError, match=rf"^{path}: field 'n_steps': must be an integer .* got '256'"):
        load_config(path)


def test_the_env_refuses_a_numeric_string() -> None:
    import gymnasium as gym

    with pytest.raises(ValueError, match=r"field 'wind_speed_kmh': .* got '50'"):
        gym.make("DSS14-v0", wind_speed_kmh="50")


@pytest.mark.parametrize("key, value", [
    ("torch_threads", 100000), ("seed", 1e23), ("net_arch", [10**9]), ("n_envs", 10**6),
    ("eval_seeds", [2**40]), ("n_steps", 10**8), ("total_timesteps", 10**12),
])
def test_values_torch_numpy_or_sb3_cannot_take_are_refused_before_the_folder(
        tmp_path: Path, key: str, value, capsys) -> None:
    path = _write(tmp_path / "c.yaml", {**TINY, key: value})
    out = tmp_path / "out"
    assert cli.main(["train", "ppo", "--config", str(path), "--out", str(out)]) == 2
    _one_line(capsys, str(path), f"field '{key}'")
    assert not out.exists()


def test_seed_indices_past_the_largest_seed_are_refused(tmp_path: Path, capsys) -> None:
    path = _write(tmp_path / "c.yaml", {**TINY, "seed": MAX_SEED - 10})
    out = tmp_path / "out"
    assert cli.main(["train", "ppo", "--config", str(path), "--train-seeds", "0-1", "--out", str(out)]) == 2
    _one_line(capsys, "--train-seeds", "seed index 1")
    assert not out.exists()


def test_a_model_file_out_of_numbers_reach_names_file_and_field(tmp_path: Path) -> None:
    from dss14_env.core.schema import default_config_path
    from dss14_env.model.config import load_model_config

    raw, _ = read_config(default_config_path("model.yaml"))
    for section, key, value in (("hydraulics", "beta", 1e300), ("structure", "n_ribs", 1000)):
        tree = json.loads(json.dumps(raw))
        tree[section][key]["value"] = value
        path = _write(tmp_path / f"{key}.yaml", tree)
        with pytest.raises(ConfigError, match=rf"^{path}: field '{section}.{key}': "):
            load_model_config(path)


# ------------------------------------------------------------------ command-line numbers
@pytest.mark.parametrize("argv, words", [
    (["bench", "--wind-speeds", "95"], ["--wind-speeds", "95", "90"]),
    (["bench", "--steps", "10"], ["--steps", "warm-up"]),
    (["bench", "--threads", "100000"], ["--threads", "CPUs"]),
    (["campaign", "--plants", "1", "--wind-speeds", "95"], ["--wind-speeds", "95", "90"]),
])
def test_cli_numbers_out_of_the_envs_bounds_are_one_line_before_work(tmp_path: Path, capsys,
                                                                      argv, words) -> None:
    out = tmp_path / "out"
    assert cli.main([*argv, "--out", str(out)]) == 2
    _one_line(capsys, *words)
    assert not out.exists()


# ------------------------------------------------------------------ clusters
def _closed_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_cluster_fails_at_once_naming_the_address() -> None:
    address = f"127.0.0.1:{_closed_port()}"
    t0 = time.perf_counter()
    with pytest.raises(RuntimeError, match=rf"^--address {address}: no Ray cluster can be reached"):
        probe_address(address)
    assert time.perf_counter() - t0 < 30


def test_campaign_with_an_unreachable_address_is_one_line(tmp_path: Path, capsys) -> None:
    pytest.importorskip("ray")
    address = f"127.0.0.1:{_closed_port()}"
    out = tmp_path / "c1"
    assert cli.main(["campaign", "--plants", "2", "--steps", "300", "--controllers", "pi_kp1",
                     "--address", address, "--out", str(out)]) == 2
    _one_line(capsys, address)
    assert not out.exists()


@pytest.mark.parametrize("address, want", [
    ("auto", None), ("10.0.0.1:6380", ("10.0.0.1", 6380)), ("head", ("head", 6379)),
    ("ray://head", ("head", 10001)), ("ray://head:10002", ("head", 10002)),
])
def test_cluster_addresses_are_split(address: str, want) -> None:
    assert split_address(address) == want


@pytest.mark.parametrize("address", ["head:port", "head:0", "head:99999", ":6379"])
def test_bad_cluster_addresses_are_named(address: str) -> None:
    with pytest.raises(ValueError, match="--address"):
        split_address(address)
