"""The learned agents' evaluation tasks (agents/evaluation.py) on the bench's episode loop: every
bench scenario is a task, and a task's figures are the bench runner's for the same seeds and
length."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dss14_env.agents.evaluation import (
    DEFAULT_SCENARIOS,
    DSS14_TASKS,
    FIGURES,
    FINAL_SCORING,
    SCENARIO_TASKS,
    TEST_SEED_RANGE,
    TEST_SEEDS,
    TEST_STEPS,
    TRAINING_SEED_START,
    VALIDATION_SEED_RANGE,
    dss14_tasks,
    run_task,
)
from dss14_env.baselines.pi import PIController
from dss14_env.bench.catalog import SCENARIO_ROWS, SCENARIOS
from dss14_env.bench.runner import run
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.presets import PRESETS


def test_the_held_out_protocol_is_unchanged() -> None:
    """Test seeds 0-9 of 0-999 (60-s episodes), validation 1000-9999, training from 10 000."""
    assert TEST_SEEDS == tuple(range(10)) and TEST_STEPS == 3000
    assert TEST_SEED_RANGE == (0, 1000) and VALIDATION_SEED_RANGE == (1000, 10_000)
    assert TRAINING_SEED_START == 10_000
    assert DEFAULT_SCENARIOS == ("hold_front", "hold_side")
    assert [t.name for t in DSS14_TASKS] == list(DEFAULT_SCENARIOS)


@pytest.mark.parametrize("row", SCENARIO_ROWS, ids=lambda r: r.name)
def test_every_bench_scenario_is_a_task_of_the_same_episodes(row) -> None:
    """A task runs its bench scenario: the same environment keys, the default bench run's
    episode length and the warm-up."""
    assert row.name in SCENARIO_TASKS
    (task,) = dss14_tasks(scenarios=[row.name])
    sc = row.scenario()
    assert {**PRESETS[task.preset].kwargs, **task.env_kwargs} == dict(sc.env)
    steps = task.steps if task.steps is not None else PRESETS[task.preset].max_episode_steps
    assert steps == round(row.default.seconds / 0.02)
    assert task.warmup_steps * 0.02 == pytest.approx(sc.warmup_s)
    assert task.axis == (row.loaded_axes[0] if len(row.loaded_axes) == 1 else None)


def test_env_kwargs_lay_over_every_scenario() -> None:
    tasks = dss14_tasks({"dt": 0.01, "wind_speed_kmh": 30.0}, scenarios=["hold_side_axis", "track"])
    assert [t.name for t in tasks] == ["hold_side_axis", "track"]
    assert tasks[0].env_kwargs == {"encoders": "axis", "dt": 0.01, "wind_speed_kmh": 30.0}
    assert tasks[0].warmup_steps == 500 and tasks[1].axis is None and tasks[1].pointing_axis is None


@pytest.mark.parametrize("bad", [["hold_left"], ["nope"], [], ["step", "step"]])
def test_unknown_scenarios_are_refused(bad) -> None:
    with pytest.raises(ValueError, match="evaluation scenarios"):
        dss14_tasks(scenarios=bad)


def _pi(env) -> PIController:
    return PIController(env, "kp1")


@pytest.mark.parametrize(("name", "steps"), [("step", 200), ("track", 300), ("slew", 300),
                                             ("hold_front_axis", 300)])
def test_task_figures_equal_the_bench_runners(name: str, steps: int) -> None:
    """run_task's per-episode figures are the bench's on the same seeds and length (the same
    episode loop and figures), for every scenario kind."""
    (task,) = dss14_tasks(scenarios=[name])
    env = DSS14Env(**{**PRESETS[task.preset].kwargs, **task.env_kwargs})
    res = run_task(_pi(env), task, [3, 4], steps, access=FINAL_SCORING)
    bench = run(["pi_kp1"], [name], seeds=[3, 4], steps=steps)["episodes"]
    assert [e["seed"] for e in res["episodes"]] == [3, 4]
    for key, path in FIGURES.items():
        want = []
        for ep in bench:
            v = ep
            for p in path:
                v = v.get(p) if isinstance(v, dict) else None
            want.append(math.nan if v is None else float(v))
        np.testing.assert_allclose(res[key], want, rtol=1e-9, err_msg=key)
    np.testing.assert_array_equal(res["terminated"], [e["terminated"] for e in bench])
    np.testing.assert_array_equal(res["lengths"], [e["n_steps"] for e in bench])
    if name == "step":  # both axes step: overshoot and settling (inf: not yet settled) are scored
        assert (res["overshoot_pct_az"] > 0).all() and not np.isnan(res["settling_time_s_el"]).any()
    else:
        assert np.isnan(res["overshoot_pct_az"]).all()


def test_returns_are_the_episodes_summed_rewards() -> None:
    """The batched run's return of a row is the single environment's summed reward of that
    seed (the rewards of a row are summed until its episode ends)."""
    (task,) = dss14_tasks(scenarios=["slew"])
    kw = {**PRESETS[task.preset].kwargs, **task.env_kwargs}
    env = DSS14Env(**kw)
    res = run_task(_pi(env), task, [1005, 1006], 150)
    ctrl = _pi(env)
    obs, _ = env.reset(seed=1006)
    ctrl.reset(1006)
    total = 0.0
    for _ in range(150):
        obs, r, term, _, _ = env.step(ctrl.act(obs))
        total += r
        if term:
            break
    assert res["returns"][1] == pytest.approx(total, rel=1e-6)  # vector vs single env: rounding
    assert res["returns"][0] != pytest.approx(res["returns"][1], rel=1e-3)


def test_later_episodes_continue_each_rows_generator() -> None:
    """With n_episodes 2 the first episode of every seed is the seeded one, the second a new
    episode of the same generator."""
    task = DSS14_TASKS[1]
    env = DSS14Env(**PRESETS[task.preset].kwargs)
    one = run_task(_pi(env), task, [1000, 1001], 300)
    two = run_task(_pi(env), task, [1000, 1001], 300, n_episodes=2)
    assert two["three_sigma_mdeg"].shape == (4,)
    np.testing.assert_allclose(two["three_sigma_mdeg"][:2], one["three_sigma_mdeg"], rtol=1e-12)
    assert not np.allclose(two["three_sigma_mdeg"][2:], one["three_sigma_mdeg"], rtol=1e-3)


def test_an_unbatchable_controller_runs_one_episode_at_a_time() -> None:
    """A controller without the batch interface runs on the single environment, seed by seed,
    with the same figures."""
    task = DSS14_TASKS[0]
    env = DSS14Env(**PRESETS[task.preset].kwargs)

    class OneAtATime(PIController):
        batchable = False

    batched = run_task(_pi(env), task, [1002, 1007], 300)
    single = run_task(OneAtATime(env, "kp1"), task, [1002, 1007], 300)
    np.testing.assert_allclose(single["three_sigma_mdeg"], batched["three_sigma_mdeg"], rtol=1e-6)
    np.testing.assert_allclose(single["returns"], batched["returns"], rtol=1e-6)


def test_bench_scenario_budgets_are_the_catalogs() -> None:
    """The track, step and slew tasks run the default bench's episode lengths (40, 20, 50 s)."""
    assert SCENARIOS["step"].scenario().steps == SCENARIO_TASKS["step"][2] == 1000
    assert SCENARIOS["slew"].scenario().steps == SCENARIO_TASKS["slew"][2] == 2500
    assert SCENARIO_TASKS["track"][2] == 2000
    assert TEST_STEPS == round(SCENARIOS["hold_front"].default.seconds / 0.02)


@pytest.mark.slow
@pytest.mark.parametrize("row", ["ppo", "ppo_residual_lqg"])
@pytest.mark.parametrize("scenario", ["track", "step", "slew"])
def test_regression_shipped_residual_policies_score_their_committed_bench_figures(row: str, scenario: str,
                                                                                 check_rescored) -> None:
    """Regression check: a shipped residual policy scored by run_task in the track, step and
    slew (the default bench lengths, first 8 seeds) gives the committed bench run's episodes
    within the scatter between CPU kinds (``tests/conftest.py``; on the machine kind of the
    committed run they reproduce to its 6 significant digits), and none terminates."""
    import json
    from pathlib import Path

    from dss14_env.bench.catalog import CONTROLLERS

    bench = json.loads((Path(__file__).resolve().parents[1] / "docs" / "results"
                        / "bench_default.json").read_text())
    col = bench["episodes"][row][scenario]
    seeds = list(col["seed"])[:8]
    (task,) = dss14_tasks(scenarios=[scenario])
    res = run_task(CONTROLLERS[row].make(DSS14Env(**PRESETS[task.preset].kwargs)), task, seeds,
                   access=FINAL_SCORING)
    check_rescored({ax: (res[f"servo_three_sigma_mdeg_{ax}"], col[f"servo_error_mdeg.{ax}.three_sigma"][:8])
                    for ax in ("az", "el")})
    assert not res["terminated"].any()


# ------------------------------------------------------------------------------ sealed test seeds
def test_validation_on_a_sealed_test_seed_is_refused_and_the_final_scoring_reads_it() -> None:
    """Every evaluation path goes through run_task's guard: without the final scoring's token a
    test seed is refused before any work, naming it; with the token the same call scores."""
    from dss14_env.agents.evaluation import FINAL_SCORING, SealedSeedError

    task = DSS14_TASKS[0]
    env = DSS14Env(**PRESETS[task.preset].kwargs)
    with pytest.raises(SealedSeedError, match=r"run_task hold_front: seed 3 is a sealed test seed \(0-999\)"):
        run_task(_pi(env), task, [1000, 3], 20)
    res = run_task(_pi(env), task, [3], 20, access=FINAL_SCORING)
    assert res["lengths"].tolist() == [20]
    assert run_task(_pi(env), task, [1000], 20)["lengths"].tolist() == [20]  # validation seeds: open


def test_selection_references_and_sweeps_cannot_read_the_test_seeds(tmp_path) -> None:
    """The selection's reference runs (validation) and a sweep (recipe research) are refused the
    test seeds; a sweep is refused before it makes its folder."""
    from dss14_env.agents.campaign_report import reference_runs
    from dss14_env.agents.evaluation import SealedSeedError
    from dss14_env.agents.sweep import train_sweep

    with pytest.raises(SealedSeedError, match="seed 0 is a sealed test seed"):
        reference_runs("pi_kp1", list(DSS14_TASKS), [0], 20)
    with pytest.raises(SealedSeedError, match="sweep: test_seeds: seed 9 is a sealed test seed"):
        train_sweep({"algo": "ppo", "sweep": {"learning_rate": [1e-4, 3e-4]}}, [0], tmp_path / "s",
                    test_seeds=(9,))
    assert not (tmp_path / "s").exists()
