"""A campaign's test scenarios (``test_scenarios``), its references, ``summary.md`` and the RL
table's tracking, step and slew columns (agents/campaign_report.py, agents/results.py)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from dss14_env.agents.campaign import campaign_tasks, train_seeds
from dss14_env.agents.campaign_report import (
    REFERENCES,
    reference_controller,
    reference_scores,
    summary_markdown,
    task_scores,
)
from dss14_env.agents.config import TrainConfig
from dss14_env.agents.evaluation import FINAL_SCORING, dss14_tasks
from dss14_env.agents.results import (
    SCENARIO_COLUMNS,
    build_results,
    column_summary,
    column_values,
    main_table,
)
from dss14_env.bench.catalog import CONTROLLERS
from dss14_env.bench.runner import run
from dss14_env.core.schema import ConfigError

ALL = ["hold_front", "hold_side", "track", "step", "slew"]


# ------------------------------------------------------------------------------ config
def test_test_scenarios_default_to_the_holds_and_take_every_bench_scenario() -> None:
    cfg = TrainConfig.from_dict({"env_id": "DSS14-Plain-v0"})
    assert cfg.test_scenarios == ["hold_front", "hold_side"]
    assert [t.name for t in campaign_tasks(cfg)] == ["hold_front", "hold_side"]
    cfg = TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "test_scenarios": ALL})
    tasks = campaign_tasks(cfg)
    assert [t.name for t in tasks] == ALL
    assert [t.axis for t in tasks] == ["el", "az", None, None, None]


@pytest.mark.parametrize("bad, match", [(["nope"], "must be one of"), ([], "must be a list"),
                                        (["step", "step"], "each scenario once"),
                                        ("track", "must be a list")])
def test_bad_test_scenarios_are_refused_naming_the_key(bad, match) -> None:
    with pytest.raises(ConfigError, match=f"field 'test_scenarios': {match}"):
        TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "test_scenarios": bad})


def test_test_scenarios_need_a_dss14_environment() -> None:
    cfg = TrainConfig.from_dict({"env_id": "Pendulum-v1", "test_scenarios": ["track"]})
    with pytest.raises(ValueError, match="'test_scenarios'.*not a DSS14"):
        campaign_tasks(cfg)
    assert campaign_tasks(TrainConfig.from_dict({"env_id": "Pendulum-v1"}))[0].name == "eval"


# ------------------------------------------------------------------------------ references
@pytest.mark.parametrize("name", sorted(REFERENCES))
def test_references_are_the_bench_rows(name: str) -> None:
    _, module, cls, args = REFERENCES[name]
    row = CONTROLLERS[name]
    assert (row.module, row.cls, row.args) == (module, cls, args)


def _short(names: list[str], steps: int = 200) -> list:
    return [dataclasses.replace(t, steps=steps) for t in dss14_tasks(scenarios=names)]


def test_reference_scores_are_the_bench_figures() -> None:
    """The LQG reference of a campaign scores the bench's figures on the same episodes."""
    tasks = _short(["track", "step"])
    refs = reference_scores(tasks, [0, 1], None, FINAL_SCORING)
    assert set(refs) == set(REFERENCES)
    bench = run(["lqg"], [("step", _scenario("step", 200))], seeds=[0, 1])["episodes"]
    got = refs["lqg"]["step"]["figures"]
    np.testing.assert_allclose(got["overshoot_pct_el"], [e["step"]["el"]["overshoot_pct"] for e in bench],
                               rtol=1e-9)
    np.testing.assert_allclose(got["servo_three_sigma_mdeg_az"],
                               [e["servo_error_mdeg"]["az"]["three_sigma"] for e in bench], rtol=1e-9)
    assert "overshoot_pct_az" not in refs["lqg"]["track"]["figures"]  # no step in the track
    assert refs["pi_kp1"]["track"]["figures"]["terminated"] == [False, False]


def _scenario(name: str, steps: int):
    from dss14_env.bench.catalog import SCENARIOS, replace_steps
    return replace_steps(SCENARIOS[name].scenario(), steps)


def test_task_scores_keep_the_figures_of_every_episode() -> None:
    tasks = _short(["hold_side", "slew"], 300)
    from dss14_env.envs.env import DSS14Env
    ctrl = reference_controller("pi_kp1", DSS14Env())
    d = task_scores(ctrl, tasks, [3, 4], 300, FINAL_SCORING)
    assert d["hold_side"]["axis"] == "az" and len(d["hold_side"]["three_sigma_mdeg"]) == 2
    assert d["hold_side"]["three_sigma_mdeg"] == d["hold_side"]["figures"]["servo_three_sigma_mdeg_az"]
    assert set(d["slew"]["figures"]) >= {"servo_three_sigma_mdeg_az", "pointing_three_sigma_mdeg_xel",
                                         "rate_limit_hits", "terminated"}
    assert "three_sigma_mdeg" not in d["slew"]


# ------------------------------------------------------------------------------ columns
def test_column_values_take_the_worse_axis() -> None:
    figs = {"overshoot_pct_az": [1.0, float("nan")], "overshoot_pct_el": [3.0, 2.0],
            "settling_time_s_az": [1.0, math.inf], "settling_time_s_el": [0.5, 1.0],
            "servo_three_sigma_mdeg_az": [4.0, 5.0], "servo_three_sigma_mdeg_el": [6.0, 1.0],
            "terminated": [True, False]}
    np.testing.assert_array_equal(column_values("step", "overshoot", figs), [3.0, 2.0])
    np.testing.assert_array_equal(column_values("step", "settling", figs), [1.0, math.inf])
    np.testing.assert_array_equal(column_values("slew", "servo", figs), [6.0, 5.0])
    np.testing.assert_array_equal(column_values("track", "servo_az", figs), [4.0, 5.0])
    np.testing.assert_array_equal(column_values("slew", "terminated", figs), [1.0, 0.0])


def test_column_summary_statistics() -> None:
    rng = np.random.default_rng(0)
    x = rng.uniform(1.0, 2.0, (5, 4))
    d = column_summary(x, "servo", np.random.default_rng(0))
    assert d["iqm"]["value"] == pytest.approx(float(np.sort(x.mean(axis=1))[1:4].mean()))
    lo, hi = d["iqm"]["ci95"]
    assert lo <= d["iqm"]["value"] <= hi
    r = column_summary(x[0], "servo", np.random.default_rng(0))
    assert r["mean"]["value"] == pytest.approx(x[0].mean())
    x[1, 2] = math.inf
    bad = column_summary(x, "settling", np.random.default_rng(0))
    assert "iqm" not in bad and bad["non_finite"] == bad["infinite"] == 1
    t = column_summary(np.array([[1.0, 0.0], [1.0, 1.0]]), "terminated", np.random.default_rng(0))
    assert t["count"] == 3 and t["episodes"] == 4 and t["per_seed"] == [1, 2]


def _figures(rng: np.random.Generator, scale: float, n: int) -> dict:
    """Synthetic figures of n test episodes of the track, step and slew."""
    f = {f"servo_three_sigma_mdeg_{a}": (scale * rng.uniform(1, 2, n)).tolist() for a in ("az", "el")}
    f.update({f"overshoot_pct_{a}": (scale * rng.uniform(5, 10, n)).tolist() for a in ("az", "el")})
    f.update({f"settling_time_s_{a}": (scale * rng.uniform(1, 3, n)).tolist() for a in ("az", "el")})
    f["terminated"] = [False] * n
    return f


def _summary(n_seeds: int = 5, n_test: int = 4) -> dict:
    rng = np.random.default_rng(3)
    per_seed = []
    for k in range(n_seeds):
        res = {h: {"three_sigma_mdeg": rng.uniform(1, 2, n_test).tolist(),
                   "pointing_three_sigma_mdeg": rng.uniform(1, 2, n_test).tolist()}
               for h in ("hold_front", "hold_side")}
        res.update({s: {"returns": [0.0] * n_test, "figures": _figures(rng, 2.0, n_test)}
                    for s in ("track", "step", "slew")})
        per_seed.append({"seed_index": k, "training_seed": 10_000 + 1000 * k, "wall_s": 1.0,
                         "env_steps": 100, "final": res, "best": res})
    tasks = [{"name": t.name, "axis": t.axis, "pointing_axis": t.pointing_axis}
             for t in dss14_tasks(scenarios=ALL)]
    return {"algo": "ppo", "env_id": "DSS14-Plain-v0", "config": "x.yaml",
            "training_seeds": [e["training_seed"] for e in per_seed],
            "protocol": {"test_seeds": list(range(n_test)), "test_steps": 3000, "tasks": tasks},
            "per_seed": per_seed}


def test_summary_markdown_has_every_seed_the_iqm_and_the_references() -> None:
    s = _summary()
    ref = {h: {"three_sigma_mdeg": [2.0, 2.0, 4.0, 4.0], "pointing_three_sigma_mdeg": [1.0] * 4}
           for h in ("hold_front", "hold_side")}
    slew = _figures(np.random.default_rng(1), 1.0, 4)
    ref["slew"] = {"figures": {**slew, "terminated": [True, False, False, False]}}
    s["references"] = {"test": {"pi_kp1": ref}}
    md = summary_markdown(s)
    lines = [ln for ln in md.splitlines() if ln.startswith("| ")]
    assert len(lines) == 1 + 5 + 1 + 1  # head, seeds, IQM, PI
    x = np.array([e["best"]["hold_front"]["three_sigma_mdeg"] for e in s["per_seed"]]).mean(axis=1)
    iqm = float(np.sort(x)[1:4].mean())  # 5 seeds: the middle three
    iqm_row = lines[6].split(" | ")
    assert iqm_row[0] == "| IQM over 5 training seeds" and iqm_row[1].startswith(f"**{iqm:.3g} [")
    pi_row = lines[7].split(" | ")
    assert pi_row[1].startswith("3 [") and pi_row[-1] == "1 of 4 |"  # mean 3 mdeg; 1 slew terminated
    assert lines[7].count("–") == 4  # track and step not measured for the reference
    first = np.mean(s["per_seed"][0]["best"]["hold_front"]["three_sigma_mdeg"])
    assert f"seed 0 (10000) | {first:.3g} (" in md


def test_the_rl_table_gains_tracking_step_and_slew_only_with_figures() -> None:
    """The third table appears when a row has the scenarios' figures, with the agents' IQM
    and the references' means; rows without them get none."""
    s = _summary()
    holds = {h: [1.5] * 4 for h in ("hold_front", "hold_side")}
    refs = {"pi_kp1": ("PI", holds), "lqg": ("LQG", holds)}
    scen = {"pi_kp1": {"step": _figures(np.random.default_rng(2), 1.0, 4)}}
    res = build_results({"a": ("agent a", s, {})}, refs, list(range(4)), scenario_references=scen)
    assert "scenarios" not in res["rows"]["lqg"]
    assert set(res["rows"]["pi_kp1"]["scenarios"]) == {"step"}
    table = main_table(res)
    assert "**Tracking, step and slew**" in table
    part = table.split("**Tracking, step and slew**")[1]
    rows = [ln for ln in part.splitlines() if ln.startswith("| ")]
    assert [r.split(" | ")[0] for r in rows[1:]] == ["| PI", "| agent a"]
    n_cols = 2 + sum(len(c) for c in SCENARIO_COLUMNS.values())
    assert all(r.count(" | ") == n_cols - 1 for r in rows[2:])
    assert "| PI | 4 | – | – | " in part  # no track figures for the reference
    step = res["rows"]["a"]["scenarios"]["step"]["overshoot"]
    x = np.array([column_values("step", "overshoot", e["best"]["step"]["figures"]) for e in s["per_seed"]])
    assert step["iqm"]["value"] == pytest.approx(float(np.sort(x.mean(axis=1))[1:4].mean()))
    res["rows"] = {k: r for k, r in res["rows"].items() if not r.get("scenarios")}
    assert "Tracking" not in main_table(res)


# ------------------------------------------------------------------------------ campaign
@pytest.mark.slow
def test_a_campaign_scores_every_scenario_and_writes_summary_md(tmp_path: Path) -> None:
    """A tiny campaign with every test scenario: per seed and task the bench's figures, the
    references on the same test episodes, summary.md and curves with reference lines."""
    cfg = dict(algo="ppo", env_id="DSS14-Plain-v0", env_kwargs={"max_episode_steps": 100, "history": 2},
               n_envs=2, n_steps=64, batch_size=64, n_epochs=1, net_arch=[8], total_timesteps=128,
               eval_freq=64, eval_seeds=[1000], eval_episode_steps=300, checkpoint_freq=0,
               progress_bar=False, verbose=0, select_by="three_sigma", test_scenarios=ALL)
    out = train_seeds(cfg, [0, 1], tmp_path / "c", test_seeds=(0, 1), test_steps=300)
    s = json.loads((out / "summary.json").read_text())
    assert [t["name"] for t in s["protocol"]["tasks"]] == ALL
    assert [t["steps"] for t in s["protocol"]["tasks"]] == [300, 300, 2000, 1000, 2500]
    for e in s["per_seed"]:
        assert len(e["best"]["step"]["figures"]["overshoot_pct_el"]) == 2
    assert set(s["references"]["test"]) == {"pi_kp1", "lqg"}
    assert set(s["references"]["validation"]["lqg"]) == {"hold_front", "hold_side"}
    assert "figures" in s["aggregate"]["best"]["slew"]
    md = (out / "summary.md").read_text()
    assert "IQM over 2 training seeds" in md and "LQG, same test seeds" in md
    assert (out / "curves_hold_front.png").is_file() and not (out / "curves_track.png").exists()


def test_dss14_train_seeds_prints_summary_md(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``dss14 train --seeds`` ends by printing the campaign's summary.md (any environment: a
    return column without references)."""
    import yaml

    from dss14_env.cli import main

    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump({"algo": "ppo", "env_id": "Pendulum-v1", "n_envs": 1, "n_steps": 32,
                                    "batch_size": 32, "n_epochs": 1, "net_arch": [8],
                                    "total_timesteps": 32, "eval_freq": 0, "checkpoint_freq": 0,
                                    "progress_bar": False, "verbose": 0}))
    assert main(["train", "ppo", "--config", str(path), "--train-seeds", "0",
                 "--out", str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    md = (tmp_path / "c" / "summary.md").read_text()
    assert md in out and "| seed 0 (10000) |" in md and "eval return" in md
    assert "IQM over 1 training seed" in md and "same test seeds" not in md
