"""Hyperparameter sweeps: the ``sweep`` key of a training configuration (agents/config.py), the
grid and its labels, bad specifications named in one line, and ``train_sweep`` / ``dss14 train
--seeds`` with a sweep (agents/sweep.py): one campaign per point, sweep.json consistent with the
points' summary.json, ``--resume``; a configuration without a sweep is unchanged."""

from __future__ import annotations

import itertools
import json
import re
import shutil
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from dss14_env.agents.campaign import train_seeds
from dss14_env.agents.config import (
    MAX_LABEL_CHARS,
    TrainConfig,
    keys_of,
    load_config,
    point_labels,
    sweep_grid,
)
from dss14_env.agents.envs import check_env
from dss14_env.agents.sweep import train_sweep
from dss14_env.agents.train import train
from dss14_env.cli import main
from dss14_env.core.outdir import MANIFEST
from dss14_env.core.schema import ConfigError

#: a training run of about a second (Pendulum: no DSS14 model to build)
TINY = dict(algo="ppo", env_id="Pendulum-v1", n_envs=2, vec_env="dummy", total_timesteps=128, seed=0,
            n_steps=64, batch_size=64, n_epochs=1, net_arch=[8], eval_freq=64, eval_seeds=[7],
            checkpoint_freq=0, progress_bar=False, verbose=0)
SWEEP = {"learning_rate": [3.0e-4, 1.0e-2]}
SEEDS = [0, 1]
TEST = dict(test_seeds=(2000, 2001))
SAFE = re.compile(r"[A-Za-z0-9._+,=-]+")


def _write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _json(path: Path) -> dict:
    return json.loads(path.read_text())


def _numbers(summary: dict) -> dict:
    """A summary's numbers (the wall times left out: they are measured, not computed)."""
    per_seed = [{k: v for k, v in e.items() if k != "wall_s"} for e in summary["per_seed"]]
    return {"per_seed": per_seed, "aggregate": summary["aggregate"],
            "training_seeds": summary["training_seeds"]}


# ------------------------------------------------------------------ grid and labels
def test_grid_is_the_cartesian_product_in_key_order() -> None:
    cfg = TrainConfig.from_dict({**TINY, "sweep": {"learning_rate": [1e-4, 3e-4],
                                                   "log_std_init": [-2.5, -1.5, 0]}})
    assert cfg.sweep == {"learning_rate": [1e-4, 3e-4], "log_std_init": [-2.5, -1.5, 0.0]}
    points = cfg.points()
    assert [p.values for p in points] == [{"learning_rate": lr, "log_std_init": s}
                                          for lr in (1e-4, 3e-4) for s in (-2.5, -1.5, 0.0)]
    assert [p.label for p in points][:2] == ["learning_rate=0.0001,log_std_init=-2.5",
                                            "learning_rate=0.0001,log_std_init=-1.5"]
    for p in points:  # each point: the base with its values, and no sweep
        assert p.config.sweep == {} and "sweep" not in p.config.to_dict()
        assert p.config == TrainConfig.from_dict({**TINY, **p.values})
        assert p.label in p.config.source and p.config.source.startswith("<dict>")
    assert TrainConfig.from_dict(TINY).points() == []


def test_dotted_keys_set_one_entry_of_a_mapping() -> None:
    cfg = TrainConfig.from_dict({**TINY, "env_kwargs": {"g": 9.0}, "sweep": {"env_kwargs.g": [9.5, 10.0],
                                                                            "eval_env_kwargs.g": [8.0]}})
    assert [(p.label, p.config.env_kwargs, p.config.eval_env_kwargs) for p in cfg.points()] == [
        ("env_kwargs.g=9.5,eval_env_kwargs.g=8.0", {"g": 9.5}, {"g": 8.0}),
        ("env_kwargs.g=10.0,eval_env_kwargs.g=8.0", {"g": 10.0}, {"g": 8.0})]
    assert cfg.env_kwargs == {"g": 9.0}  # the base keeps its own value


def test_labels_fall_back_to_numbers_when_they_clash_or_are_long() -> None:
    assert point_labels([{"env_id": "a/b"}, {"env_id": "a b"}]) == ["point_00", "point_01"]
    assert point_labels([{"env_kwargs.x": "y" * MAX_LABEL_CHARS}]) == ["point_00"]
    assert point_labels([{"net_arch": {"pi": [8], "vf": [8]}}]) == ["net_arch=pi_8_vf_8"]
    assert point_labels([{"k": True, "n": None, "x": 3e-05}]) == ["k=true,n=null,x=3e-05"]
    assert point_labels([{"k": i} for i in range(101)])[-1] == "k=100"
    assert point_labels([{"k": "y" * 200, "i": i} for i in range(101)])[-1] == "point_100"


scalars = st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.integers(-10**6, 10**6),
                    st.booleans(), st.none(), st.text(max_size=12))
values = st.one_of(scalars, st.lists(scalars, max_size=3),
                   st.dictionaries(st.text(max_size=4), scalars, max_size=2))


@settings(max_examples=200, deadline=None)
@given(spec=st.dictionaries(st.from_regex(r"[a-z_]{1,10}(\.[a-z_]{1,6})?", fullmatch=True),
                            st.lists(values, min_size=1, max_size=3,
                                     unique_by=lambda v: json.dumps(v, sort_keys=True)),
                            min_size=1, max_size=3))
def test_labels_are_distinct_filesystem_safe_folder_names(spec: dict) -> None:
    grid = sweep_grid(spec)
    assert len(grid) == len(list(itertools.product(*spec.values())))
    labels = point_labels(grid)
    assert len(set(labels)) == len(labels) == len(grid)
    for label, point in zip(labels, grid, strict=True):
        assert SAFE.fullmatch(label) and len(label) <= MAX_LABEL_CHARS, label
        assert label.startswith("point_") or label.startswith(f"{next(iter(point))}=")


# ------------------------------------------------------------------ bad specifications
BASE_VALID = {**TINY, "n_steps": 64, "n_envs": 2, "batch_size": 64}


@pytest.mark.parametrize("sweep, field, what", [
    ({"lr": [1e-4]}, "sweep.lr", "unknown key 'lr'"),
    ({"learning_rat": [1e-4]}, "sweep.learning_rat", "did you mean 'learning_rate'"),
    ({"buffer_size": [10]}, "sweep.buffer_size", "is not a setting of algo 'ppo' (it belongs to sac)"),
    ({"seed": [1, 2]}, "sweep.seed", "cannot be swept (the seeds of a sweep are --train-seeds)"),
    ({"sweep": [{"learning_rate": [1]}]}, "sweep.sweep", "cannot be swept"),
    ({"algo": ["sac"]}, "sweep.algo", "cannot be swept"),
    ({"learning_rate": []}, "sweep.learning_rate", "must be a non-empty list of values, got []"),
    ({"learning_rate": 3e-4}, "sweep.learning_rate", "must be a non-empty list of values, got 0.0003"),
    ({"learning_rate": [3e-4, -1.0]}, "sweep.learning_rate", "must be a number > 0, got -1.0"),
    ({"learning_rate": [".nan"]}, "sweep.learning_rate", "must be a number > 0"),
    ({"n_epochs": [2, 1.5]}, "sweep.n_epochs", "must be an integer >= 1 and <= 1000, got 1.5"),
    ({"activation_fn": ["relu", "swish"]}, "sweep.activation_fn", "must be one of"),
    ({"learning_rate": [1e-4, "1e-4"]}, "sweep.learning_rate", "values must be distinct"),
    ({"env_kwargs": [{}], "env_kwargs.g": [9.0]}, "sweep.env_kwargs.g", "overlaps 'sweep.env_kwargs'"),
    ({"n_steps.x": [1]}, "sweep.n_steps.x", "a dotted key must name an entry of a mapping key"),
    ({"env_kwargs.": [1]}, "sweep", "keys must be configuration keys"),
    ({"batch_size": [64, 48]}, "batch_size", "must divide n_steps * n_envs = 128, got 48"),
    ({"net_arch": [[8], [0]]}, "net_arch", "must be a list of 1 to 16 layer sizes"),
    ({"n_epochs": list(range(1, 40)), "gamma": [0.9 + 0.001 * i for i in range(30)]}, "sweep",
     "must have at most 1000 points, got a grid of 1170"),
    ({}, "sweep", "must be a mapping of configuration keys to lists of values, got {}"),
    (None, "sweep", "must be a mapping of configuration keys to lists of values, got None"),
    ([1e-4], "sweep", "must be a mapping"),
])
def test_bad_sweep_is_one_line_naming_file_and_field(sweep, field: str, what: str, tmp_path: Path) -> None:
    path = _write(tmp_path / "s.yaml", {**BASE_VALID, "sweep": sweep})
    with pytest.raises(ConfigError) as info:
        load_config(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "\n" not in msg, msg
    assert f"field '{field}': " in msg and what in msg, msg


def test_a_sweep_key_of_the_configs_own_algorithm() -> None:
    base = {"algo": "sac", "env_id": "Pendulum-v1"}
    assert len(TrainConfig.from_dict({**base, "sweep": {"tau": [0.01, 0.02]}}).points()) == 2
    with pytest.raises(ConfigError, match=r"field 'sweep.n_epochs': is not a setting of algo 'sac' "
                                          r"\(it belongs to ppo, recurrent_ppo\)"):
        TrainConfig.from_dict({**base, "sweep": {"n_epochs": [1, 2]}})


#: values that are valid for their key (mostly), drawn with any values for any keys
GOOD = {"learning_rate": st.floats(1e-6, 1.0), "n_epochs": st.integers(1, 20),
        "gamma": st.floats(0.5, 1.0), "activation_fn": st.sampled_from(["tanh", "relu", "elu"]),
        "batch_size": st.sampled_from([32, 64, 48]), "n_steps": st.integers(32, 128),
        "net_arch": st.lists(st.integers(1, 64), min_size=1, max_size=3), "env_kwargs.g": st.floats(5, 15),
        "eval_seeds": st.lists(st.integers(0, 10_000), min_size=1, max_size=3)}
sweep_keys = st.sampled_from([*GOOD, "env_kwargs", "seed", "sweep", "algo", "buffer_size", "bogus",
                              "select_by"])


@st.composite
def sweeps(draw) -> object:
    """A sweep specification: often of valid keys and values, sometimes anything."""
    if draw(st.integers(0, 9)) == 0:
        return draw(values)
    spec = {}
    for key in draw(st.lists(sweep_keys, min_size=1, max_size=3, unique=True)):
        good = GOOD.get(key, values) if draw(st.integers(0, 4)) else values
        spec[key] = draw(st.one_of(st.lists(good, min_size=1, max_size=3), values) if draw(st.integers(0, 9))
                         == 0 else st.lists(good, min_size=1, max_size=3))
    return spec


@settings(max_examples=200, deadline=None)
@given(spec=sweeps())
def test_any_sweep_loads_or_names_its_field(spec, tmp_path_factory) -> None:
    path = _write(tmp_path_factory.mktemp("s") / "s.yaml", {**BASE_VALID, "sweep": spec})
    try:
        cfg = load_config(path)
    except ConfigError as exc:
        msg = str(exc)
        assert msg.startswith(str(path)) and "\n" not in msg and "field '" in msg, msg
        return
    points = cfg.points()
    assert len(points) == len(sweep_grid(cfg.sweep)) == len(list(itertools.product(*spec.values())))
    assert len({p.label for p in points}) == len(points)
    for p in points:  # every point is a configuration, and a file of its own loads back the same
        assert TrainConfig.from_dict(yaml.safe_load(yaml.safe_dump(p.config.to_dict()))) == p.config
    assert TrainConfig.from_dict(yaml.safe_load(yaml.safe_dump(cfg.to_dict()))) == cfg


# ------------------------------------------------------------------ without a sweep: unchanged
def test_a_config_without_sweep_is_unchanged(tmp_path: Path) -> None:
    cfg = TrainConfig.from_dict(TINY)
    assert list(cfg.to_dict()) == keys_of("ppo") and cfg.sweep == {}
    swept = TrainConfig.from_dict({**TINY, "sweep": SWEEP})
    assert list(swept.to_dict()) == keys_of("ppo") + ["sweep"] and swept != cfg
    assert swept.replace(sweep={}) == cfg and swept.replace(n_epochs=2).sweep == swept.sweep
    assert cfg.replace(sweep=SWEEP) == swept
    # the shipped configurations other than the example sweep have none
    for name in ("ppo", "ppo_plain", "ppo_smoke", "sac", "recurrent_ppo"):
        assert load_config(name).sweep == {}


def test_the_shipped_example_sweep_is_the_plain_recipe_with_a_grid() -> None:
    cfg = load_config("ppo_plain_sweep")
    assert cfg.replace(sweep={}).to_dict() == load_config("ppo_plain").to_dict()
    assert cfg.sweep == {"learning_rate": [1e-4, 3e-4], "log_std_init": [-2.5, -1.5]}
    points = cfg.points()
    assert [p.label for p in points] == [f"learning_rate={lr},log_std_init={s}" for lr in ("0.0001", "0.0003")
                                         for s in ("-2.5", "-1.5")]
    _, obs, act, env_cfg = check_env(points[0].config)  # the recipe's environment
    assert obs.shape == (40,) and act.shape == (2,) and env_cfg.action_scale_deg_s == 0.02


def test_a_sweep_refuses_single_run_commands(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = _write(tmp_path / "s.yaml", {**TINY, "sweep": SWEEP})
    with pytest.raises(ValueError, match=r"s.yaml: field 'sweep': a sweep trains one campaign per point"):
        train(str(path), run_dir=tmp_path / "run")
    with pytest.raises(ValueError, match=r"field 'sweep': a sweep trains one campaign per point"):
        train_seeds(str(path), SEEDS, tmp_path / "c")
    with pytest.raises(ValueError, match=r"field 'sweep': is missing"):
        train_sweep(TINY, SEEDS, tmp_path / "c")
    assert main(["train", "ppo", "--config", str(path), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "field 'sweep': a sweep trains one campaign per point: give --train-seeds" in err
    assert not any(p.name in ("run", "c", "x") for p in tmp_path.iterdir())


def test_a_bad_point_environment_fails_before_any_work(tmp_path: Path) -> None:
    cfg = {**TINY, "sweep": {"env_kwargs.g": [9.0], "env_kwargs.mass": [1.0]}}
    with pytest.raises(ValueError, match=r"\[sweep point env_kwargs.g=9.0,env_kwargs.mass=1.0\]: "
                                         r"key 'env_id': cannot make 'Pendulum-v1'"):
        train_sweep(cfg, SEEDS, tmp_path / "s")
    assert not (tmp_path / "s").exists()


# ------------------------------------------------------------------ a tiny sweep in-process
@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2 points x 2 seeds, in-process (``dss14 train ppo --config s.yaml --seeds 0-1``)."""
    root = tmp_path_factory.mktemp("sweep")
    path = _write(root / "s.yaml", {**TINY, "sweep": SWEEP})
    return train_sweep(str(path), SEEDS, root / "out", **TEST)


def test_sweep_writes_a_campaign_per_point_and_a_consistent_sweep_json(swept: Path) -> None:
    report = _json(swept / "sweep.json")
    labels = ["learning_rate=0.0003", "learning_rate=0.01"]
    assert sorted(p.name for p in swept.iterdir()) == sorted(["config.yaml", "sweep.json", "sweep.md",
                                                              MANIFEST, *labels])
    assert TrainConfig.from_dict(yaml.safe_load((swept / "config.yaml").read_text())) == \
        TrainConfig.from_dict({**TINY, "sweep": SWEEP})
    assert report["sweep"] == SWEEP and report["seed_indices"] == SEEDS
    assert [p["label"] for p in report["points"]] == labels
    for p, lr in zip(report["points"], SWEEP["learning_rate"], strict=True):
        sub = swept / p["folder"]
        assert p["values"] == {"learning_rate": lr}
        assert {q.name for q in sub.iterdir()} == {"config.yaml", "summary.json", "summary.md",
                                                   "curves_eval.png", "seed_0", "seed_1", MANIFEST}
        assert yaml.safe_load((sub / "config.yaml").read_text())["learning_rate"] == lr
        summary = _json(sub / "summary.json")
        assert summary["training_seeds"] == report["training_seeds"] == [0, 1000]
        assert p["aggregate"] == summary["aggregate"]  # the point's IQM, interval and per-seed values
        for which in ("final", "best"):
            agg = p["aggregate"][which]["eval"]
            assert agg["metric"] == "mean_return"
            assert agg["per_seed"] == [e[which]["eval"]["mean_return"] for e in summary["per_seed"]]
    # the two learning rates train different policies
    finals = [p["aggregate"]["final"]["eval"]["per_seed"] for p in report["points"]]
    assert finals[0] != finals[1]


def test_ranking_orders_the_points_and_marks_overlapping_intervals(swept: Path) -> None:
    report = _json(swept / "sweep.json")
    assert "not significantly different" in report["protocol"]["ranking"]
    md = (swept / "sweep.md").read_text()
    assert "not significantly different" in md
    for which in ("final", "best"):
        r = report["ranking"][which]["eval"]
        assert r["metric"] == "mean_return" and r["better"] == "higher"
        iqm = {p["label"]: p["aggregate"][which]["eval"]["iqm"] for p in report["points"]}
        assert [o["iqm"] for o in r["order"]] == sorted((v["value"] for v in iqm.values()), reverse=True)
        assert [o["rank"] for o in r["order"]] == [1, 2]
        (lo1, hi1), (lo2, hi2) = (iqm[o["label"]]["ci95"] for o in r["order"])
        assert r["order"][0]["overlaps_first"] is True
        assert r["order"][1]["overlaps_first"] == (lo2 <= hi1 and lo1 <= hi2)
        for o in r["order"]:
            cell = f"{o['iqm']:.4g} [{o['ci95'][0]:.4g}, {o['ci95'][1]:.4g}] (#{o['rank']}"
            assert cell in md, cell


def test_a_point_is_the_campaign_of_its_configuration(swept: Path, tmp_path: Path) -> None:
    """The sweep's point folder holds what train_seeds writes for the point's configuration."""
    point = TrainConfig.from_dict({**TINY, "sweep": SWEEP}).points()[1]
    alone = train_seeds(point.config, SEEDS, tmp_path / "alone", figures=False, **TEST)
    assert _numbers(_json(alone / "summary.json")) == _numbers(_json(swept / point.label / "summary.json"))


def test_interrupted_sweep_continues(swept: Path, tmp_path: Path) -> None:
    cfg_path = swept.parent / "s.yaml"
    out = tmp_path / "cut"
    shutil.copytree(swept, out)
    first, second = (out / p["folder"] for p in _json(swept / "sweep.json")["points"])
    # interrupted: a run of the second point stopped before its last file; nothing summarised
    (second / "seed_1" / "train_summary.json").unlink()
    for f in (second / "summary.json", out / "sweep.json", out / "sweep.md"):
        f.unlink()
    kept = {p: (p / "policy.pt").stat().st_mtime_ns for p in (first / "seed_0", first / "seed_1",
                                                                second / "seed_0")}
    with pytest.raises(ValueError, match="--overwrite"):
        train_sweep(str(cfg_path), SEEDS, out, **TEST)
    train_sweep(str(cfg_path), SEEDS, out, resume=True, **TEST)
    assert all((p / "policy.pt").stat().st_mtime_ns == t for p, t in kept.items())  # scored, not retrained
    assert _json(out / "sweep.json") == _json(swept / "sweep.json")
    for p in (first, second):
        assert _numbers(_json(p / "summary.json")) == _numbers(_json(swept / p.name / "summary.json"))
    # another sweep is refused, naming the sweep's file
    other = _write(tmp_path / "other.yaml", {**TINY, "sweep": {"learning_rate": [1e-3, 1e-2]}})
    with pytest.raises(ValueError, match="config.yaml is another configuration"):
        train_sweep(str(other), SEEDS, out, resume=True, **TEST)


def test_a_sweep_and_a_campaign_do_not_mix_in_one_folder(swept: Path, tmp_path: Path) -> None:
    out = tmp_path / "both"
    shutil.copytree(swept, out)
    with pytest.raises(ValueError, match=r"already holds results \(.*sweep.json"):
        train_seeds(TINY, [0], out, figures=False, **TEST)
    train_seeds({**TINY, "total_timesteps": 64, "eval_freq": 0}, [0], out, overwrite=True, figures=False,
                test_seeds=(0,))
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml", MANIFEST, "seed_0", "summary.json",
                                                     "summary.md"]


def test_overwrite_takes_only_the_sweeps_own_point_folders(swept: Path, tmp_path: Path) -> None:
    out = tmp_path / "mine"
    shutil.copytree(swept, out)
    (out / "notes=keep").mkdir()  # a folder of the user's that looks like a point label
    (out / "point_07").mkdir()
    train_seeds({**TINY, "total_timesteps": 64, "eval_freq": 0}, [0], out, overwrite=True, figures=False,
                test_seeds=(0,))
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml", MANIFEST, "notes=keep", "point_07",
                                                      "seed_0", "summary.json", "summary.md"]
