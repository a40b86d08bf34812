"""``dss14 bench`` (dss14_env/bench/bench.py): options, results.json against the runner, results.md,
figures, and the command end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dss14_env import cli
from dss14_env.bench import bench as B
from dss14_env.bench import runner

CTRLS = ["pi_kp1", "lqg"]
SCENS = ["hold_side", "step"]
STEPS = 300


# ------------------------------------------------------------------ options
@pytest.mark.parametrize("values,seeds", [(["3"], [0, 1, 2]), (["1"], [0]), (["4", "2"], [4, 2]),
                                         ([5, 7, 9], [5, 7, 9]), (None, None)])
def test_seeds_are_a_count_or_a_list(values, seeds) -> None:
    assert B.parse_seeds(values) == seeds


@pytest.mark.parametrize("values,message", [(["x"], "not an integer"), (["3", "-1"], "non-negative"),
                                            (["0"], ">= 1"), (["-2"], ">= 1"), (["1", "1"], "repeated"),
                                            ([], "give a count"), (["1.5"], "not an integer")])
def test_bad_seeds_are_named(values, message) -> None:
    with pytest.raises(B.BenchOptionError, match=f"--seeds: .*{message}"):
        B.parse_seeds(values)


def test_wind_speeds_are_sorted_floats() -> None:
    assert B.parse_wind_speeds(["70", "30", "45.5"]) == [30.0, 45.5, 70.0]


@pytest.mark.parametrize("values", [["abc"], ["0"], ["-10"], ["200"], ["nan"], ["40", "40"], []])
def test_bad_wind_speeds_are_named(values) -> None:
    with pytest.raises(B.BenchOptionError, match="--wind-speeds"):
        B.parse_wind_speeds(values)


@pytest.mark.parametrize("kwargs,message", [
    ({"controllers": ["lqr"]}, r"--controllers: unknown controller 'lqr' \(did you mean 'lqg'\?\)"),
    ({"controllers": ["lqg", "lqg"]}, "--controllers: controller named twice"),
    ({"controllers": []}, "--controllers: give at least one"),
    ({"scenarios": ["hover"]}, "--scenarios: unknown scenario 'hover'"),
    ({"scenarios": ["step", "step"]}, "--scenarios: scenario named twice"),
    ({"steps": 0}, "--steps"),
    ({"controllers": ["lqg"], "ppo_model": "x"}, "--ppo-model: given, but 'ppo' is not"),
    ({"seeds": 2, "sweep_seeds": 3}, "--sweep-seeds: a count from 1 to the number of seeds"),
    ({"sweep_seeds": 0}, "--sweep-seeds"),
])
def test_bad_options_are_named(kwargs, message) -> None:
    with pytest.raises(B.BenchOptionError, match=message):
        B.build_plan(**kwargs)


def test_missing_ppo_policy(monkeypatch, tmp_path) -> None:
    import dss14_env.agents.policy
    monkeypatch.setattr(dss14_env.agents.policy, "DEFAULT_POLICY", tmp_path / "none")
    plan = B.build_plan()  # default run: a warning, and the others run
    assert "ppo" not in plan.controllers and plan.controllers == ["pi_kp1", "pi_kp0.7", "lqg", "mpc"]
    assert len(plan.notes) == 1 and str(tmp_path / "none") in plan.notes[0]
    with pytest.raises(B.BenchOptionError, match="--controllers ppo: .*none"):
        B.build_plan(controllers=["pi_kp1", "ppo"])  # asked for: an error
    with pytest.raises(B.BenchOptionError, match="--ppo-model: .*nowhere"):
        B.build_plan(ppo_model=tmp_path / "nowhere")


def test_default_and_quick_plans(monkeypatch) -> None:
    monkeypatch.setattr(B, "_ppo_problem", lambda path: None)  # as if the policy were shipped
    plan = B.build_plan()
    assert plan.controllers == list(B.DEFAULT_CONTROLLERS) and plan.scenarios == list(B.DEFAULT_SCENARIOS)
    assert plan.seeds == list(B.DEFAULT_SEEDS) and plan.wind_speeds_kmh == [30, 40, 50, 60, 70]
    assert plan.steps == {s: B.DEFAULT_STEPS.get(s, runner.SCENARIOS[s].steps) for s in plan.scenarios}
    assert plan.sweep_directions == ["front", "side"] and plan.env_kwargs == {}
    quick = B.build_plan(quick=True)
    assert quick.seeds == [0] and len(quick.wind_speeds_kmh) < 5
    assert all(quick.steps[s] < plan.steps[s] for s in plan.scenarios)
    assert quick.sweep_steps < plan.sweep_steps
    # explicit options win over --quick; --randomize; the sweep follows the hold scenarios
    p = B.build_plan(quick=True, seeds=["2"], steps=100, randomize=True, scenarios=["hold_side", "step"])
    assert p.seeds == [0, 1] and set(p.steps.values()) == {100} and p.sweep_steps == 100
    assert p.env_kwargs == {"randomize_params": True} and p.sweep_directions == ["side"]
    assert B.build_plan(scenarios=["step"]).sweep_directions == []
    # from Python: an int is a count, ints are the seeds, strings are command-line values
    assert B.build_plan(seeds=3).seeds == [0, 1, 2] and B.build_plan(seeds=[0]).seeds == [0]
    assert B.build_plan(seeds=[4]).seeds == [4] and B.build_plan(seeds=["4"]).seeds == [0, 1, 2, 3]
    assert B.build_plan(sweep=False).sweep_directions == []
    # the sweep runs on the first seed by default; a sweep point equal to a main scenario is
    # taken from it only when the sweep runs on all the seeds
    assert plan.sweep_seeds == [0] and B.build_plan(seeds=3, sweep_seeds=2).sweep_seeds == [0, 1]
    one = B.build_plan(seeds=2, steps=100, wind_speeds=[50])
    assert [p[-1] for p in B._sweep_points(one)] == [None, None]
    both = B.build_plan(seeds=2, steps=100, wind_speeds=[50], sweep_seeds=2)
    assert [p[-1] for p in B._sweep_points(both)] == ["hold_front", "hold_side"]
    json.dumps(p.as_dict())


def test_cli_bad_option_exits_2(capsys) -> None:
    assert cli.main(["bench", "--controllers", "pi_kp1", "nope"]) == 2
    assert "--controllers: unknown controller 'nope'" in capsys.readouterr().err
    assert cli.main(["bench", "--seeds", "0", "zero"]) == 2
    assert "--seeds" in capsys.readouterr().err
    assert cli.main(["bench", "--wind-speeds", "-30"]) == 2
    assert "--wind-speeds" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        cli.main(["bench", "--steps", "many"])
    assert exc.value.code == 2


# ------------------------------------------------------------------ a tiny run
@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("bench")
    plan = B.build_plan(controllers=CTRLS, scenarios=SCENS, seeds=[0], steps=STEPS,
                        wind_speeds=["40", "50"], out=out)
    res = B.bench(plan, progress=False)
    return {"plan": plan, "res": res, "out": out,
            "json": json.loads((out / "results.json").read_text())}


def _comparable(summary: dict) -> dict:
    """A runner summary without the wall-clock figures."""
    return {k: v for k, v in summary.items() if k != "controller_time_ms"}


def test_results_json_matches_the_runner(tiny) -> None:
    js = tiny["json"]
    with B.blas_threads(1):  # the bench's setting (the last bits of BLAS sums depend on it)
        direct = runner.run(CTRLS, SCENS, [0], steps=STEPS)
    assert js["meta"]["controllers"] == CTRLS and js["meta"]["scenarios"] == SCENS
    for c in CTRLS:
        for s in SCENS:
            assert _comparable(js["summary"][c][s]) == _comparable(direct["summary"][c][s]), (c, s)
    assert js["yardstick"] == direct["yardstick"] and set(js["yardstick"]) == {"hold_side"}
    assert len(js["episodes"]) == len(direct["episodes"]) == 4
    assert all("trace" not in ep for ep in js["episodes"])


def test_results_json_records_the_run(tiny) -> None:
    js = tiny["json"]
    b = js["bench"]
    assert b["config"]["controllers"] == CTRLS and b["config"]["seeds"] == [0]
    assert b["config"]["steps"] == {s: STEPS for s in SCENS}
    assert b["wall_time_s"]["total"] > 0 and b["notes"] == []
    assert set(b["figures"]) == set(B.FIGURES)
    assert {"python", "numpy", "scipy", "gymnasium", "stable-baselines3", "torch", "cvxpy",
            "dss14-env"} <= set(js["versions"])
    assert js["versions"]["numpy"] == np.__version__


def test_wind_sweep_matches_the_runner(tiny) -> None:
    sw = tiny["json"]["wind_sweep"]
    assert sw["speeds_kmh"] == [40.0, 50.0] and sw["directions"] == ["side"]
    # the 50 km/h point is the hold_side scenario itself (same episodes), 40 km/h is run
    assert sw["points"]["hold_side_50kmh"]["same_as"] == "hold_side"
    assert sw["points"]["hold_side_40kmh"]["same_as"] is None
    cur = sw["curves"]["side"]
    assert cur["axis"] == "az"
    main = tiny["json"]["summary"]
    with B.blas_threads(1):
        direct = runner.run(CTRLS, [("p", B.sweep_scenario("side", 40, STEPS))], [0])
    for c in CTRLS:
        med = cur["three_sigma_mdeg"][c]["median"]
        assert med[0] == direct["summary"][c]["p"]["servo_error_mdeg"]["az"]["three_sigma"]["median"]
        assert med[1] == main[c]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]["median"]
    ref = cur["yardstick_three_sigma_mdeg"]
    assert ref[0] == pytest.approx(direct["yardstick"]["p"]["three_sigma_mdeg"][0])
    assert ref[1] == pytest.approx(tiny["json"]["yardstick"]["hold_side"]["three_sigma_mdeg"][0])
    assert ref[0] < ref[1]


def test_results_md_and_figures(tiny) -> None:
    md = (tiny["out"] / "results.md").read_text()
    assert md == tiny["res"]["markdown"]
    assert tiny["res"]["main_table"] in md and "## How to read it" in md
    for c in CTRLS:
        assert f"| {c} |" in md
    assert "yardstick (analytic)" in md and "Step response" in md and "side wind, 3σ az" in md
    for f in B.FIGURES:
        p = tiny["out"] / f
        assert p.is_file() and p.stat().st_size > 5000, f


def test_traces_are_opt_in(tiny) -> None:
    eps = tiny["res"]["ran"]["main"]["episodes"]
    tr = eps[0]["trace"]
    n = eps[0]["n_steps"]
    assert tr["t"].shape == (n,) and tr["t"][0] == pytest.approx(0.02)
    for k in ("servo_error_mdeg", "command_deg", "encoder_deg", "rate_command_deg_s"):
        assert tr[k].shape == (n, 2), k
    step = next(e for e in eps if e["scenario"] == "step")["trace"]
    assert step["command_deg"][-1] == pytest.approx([0.1, 0.1])
    # the metric's position (command - true error) and the encoder agree within a count or so
    pos = step["command_deg"] - step["servo_error_mdeg"] / 1e3
    assert np.max(np.abs(pos - step["encoder_deg"])) < 1e-3
    assert "trace" not in runner.run(["pi_kp1"], ["step"], [0], steps=20)["episodes"][0]


def test_an_episode_that_ends_before_the_step(tmp_path) -> None:
    plan = B.build_plan(controllers=["pi_kp1"], scenarios=["step"], seeds=[0], steps=20,
                        out=tmp_path)
    res = B.bench(plan, progress=False)
    st = res["results"]["summary"]["pi_kp1"]["step"]["step"]
    assert np.isnan(st["az"]["overshoot_pct"]["median"])
    assert "| pi_kp1 | — / — |" in res["markdown"]


def test_the_ppo_entry_loads_the_policy_on_the_env(monkeypatch, tmp_path) -> None:
    import dss14_env.agents.policy
    from dss14_env.baselines.pi import PIController

    calls = []

    def fake_load(path=None, env=None, name=None):
        calls.append((path, env))
        return PIController(env)

    monkeypatch.setattr(B, "_ppo_problem", lambda path: None)
    monkeypatch.setattr(dss14_env.agents.policy, "load_policy", fake_load)
    plan = B.build_plan(controllers=["ppo"], scenarios=["step"], seeds=["1"], steps=50,
                        out=tmp_path, figures=False)
    res = B.bench(plan, progress=False)
    assert len(calls) == 1 and calls[0][0] is None and calls[0][1] is not None
    assert set(res["results"]["summary"]) == {"ppo"} and "| ppo |" in res["markdown"]
    assert res["figures"] == [] and not (tmp_path / B.FIGURES[0]).exists()


# ------------------------------------------------------------------ end to end
def test_cli_quick_end_to_end(tmp_path, capsys) -> None:
    out = tmp_path / "tmp"
    assert cli.main(["bench", "--quick", "--controllers", "pi_kp1", "lqg", "mpc", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| mpc |" in text and "written to" in text
    js = json.loads((out / "results.json").read_text())
    assert js["meta"]["controllers"] == ["pi_kp1", "lqg", "mpc"]
    assert js["meta"]["scenarios"] == list(B.DEFAULT_SCENARIOS) and js["meta"]["seeds"] == [0]
    assert js["bench"]["command"].startswith("dss14 bench --quick")
    assert sum(v["failures"] for c in js["summary"].values() for v in c.values()) == 0
    for f in ("results.md",) + B.FIGURES:
        assert (out / f).stat().st_size > 0, f


def test_blas_threads_limits_and_restores() -> None:
    import scipy.linalg  # noqa: F401  (its OpenBLAS loaded, as blas_threads does)
    from threadpoolctl import threadpool_info

    def blas() -> list[int]:
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    before = blas()
    with B.blas_threads(1) as bt:
        assert bt.n_libraries == len(before) >= 1 and blas() == [1] * len(before)
    assert blas() == before
    with B.blas_threads(None) as bt:
        assert bt.n_libraries == 0 and blas() == before
