"""``dss14 bench`` (dss14_env/bench/): options, the output folder, results.json against the
runner, intervals recomputed from the stored episodes, results.md, figures, the README table
generated from the committed default results, and the command end to end."""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dss14_env import cli
from dss14_env.bench import bench as B
from dss14_env.bench import catalog, runner
from dss14_env.bench import figures as F
from dss14_env.bench import plan as P
from dss14_env.bench import report as R
from dss14_env.bench.run import sweep_points
from dss14_env.bench.threads import blas_threads
from dss14_env.core.outdir import MANIFEST, atomic_write_text, prepare_output_dir, update_manifest

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_RESULTS = ROOT / "docs" / "results" / "bench_default.json"
CTRLS = ["pi_kp1", "pi_kp0.7", "lqg", "mpc"]
SCENS = ["hold_side", "step"]
STEPS = 300
SEEDS = 4
SEQ = 2


# ------------------------------------------------------------------ options
@pytest.mark.parametrize("values,seeds", [(["3"], [3]), (["0-2"], [0, 1, 2]), (["4", "2"], [4, 2]),
                                         ([5, 7, 9], [5, 7, 9]), (["0-1", "5"], [0, 1, 5]), (None, None)])
def test_seeds_are_seeds_in_every_command(values, seeds) -> None:
    """--seeds has one grammar in bench and train: seeds and ranges, one value is that seed."""
    from dss14_env.agents.campaign import parse_seeds as train_seeds

    assert P.parse_seeds(values) == seeds
    if values is not None:
        assert train_seeds(values) == seeds


@pytest.mark.parametrize("values,message", [(["x"], "expected seed indices"), (["3", "-1"], "expected"),
                                            (["2-1"], "empty range"), (["1", "1"], "repeated"),
                                            ([], "no seed"), (["1.5"], "expected")])
def test_bad_seeds_are_named(values, message) -> None:
    with pytest.raises(P.BenchOptionError, match=f"--seeds: .*{message}"):
        P.parse_seeds(values)


@pytest.mark.parametrize("value,seeds,message", [("3", [0, 1, 2], None), (1, [0], None),
                                                 ("0", None, ">= 1"), ("x", None, "not an integer")])
def test_episodes_is_a_count(value, seeds, message) -> None:
    if message is None:
        assert P.parse_episodes(value) == seeds
    else:
        with pytest.raises(P.BenchOptionError, match=f"--episodes: .*{message}"):
            P.parse_episodes(value)


def test_wind_speeds_are_sorted_floats() -> None:
    assert P.parse_wind_speeds(["70", "30", "45.5"]) == [30.0, 45.5, 70.0]


@pytest.mark.parametrize("values", [["abc"], ["0"], ["-10"], ["200"], ["nan"], ["40", "40"], []])
def test_bad_wind_speeds_are_named(values) -> None:
    with pytest.raises(P.BenchOptionError, match="--wind-speeds"):
        P.parse_wind_speeds(values)


@pytest.mark.parametrize("kwargs,message", [
    ({"controllers": ["lqr"]}, r"--controllers: unknown controller 'lqr' \(did you mean 'lqg'\?\)"),
    ({"controllers": ["lqg", "lqg"]}, "--controllers: controller named twice"),
    ({"controllers": []}, "--controllers: give at least one"),
    ({"scenarios": ["hover"]}, "--scenarios: unknown scenario 'hover'"),
    ({"scenarios": ["step", "step"]}, "--scenarios: scenario named twice"),
    ({"steps": 0}, "--steps"),
    ({"steps": 2.5}, "--steps"),
    ({"controllers": ["lqg"], "ppo_model": "x"}, "--ppo-model: given, but 'ppo' is not"),
    ({"sweep_seeds": 0}, "--sweep-seeds"),
    ({"sequential_episodes": -1}, "--sequential-episodes"),
    ({"seeds": 2, "sequential_episodes": 3}, "--sequential-episodes: 3 is more than the 2 episodes"),
    ({"threads": 0}, "--threads"),
    ({"seeds": ["5", "9"], "sweep_seeds": 3}, "--sweep-seeds: 3 is more than the 2 seeds of --seeds"),
])
def test_bad_options_are_named(kwargs, message) -> None:
    with pytest.raises(P.BenchOptionError, match=message):
        P.build_plan(**kwargs)


@pytest.mark.parametrize("quick", [False, True])
def test_the_sweep_runs_on_the_seeds_given(quick: bool) -> None:
    """--seeds names the seeds of every scenario and sweep point; --sweep-seeds takes the first
    of them; a count (--episodes) leaves the sweep its own count from seed 0."""
    seeds = ["100-103", "7"]
    plan = P.build_plan(seeds=seeds, quick=quick)
    assert plan.sweep.seeds == (100, 101, 102, 103, 7)
    assert all(r.seeds == (100, 101, 102, 103, 7) for r in plan.runs.values())
    assert P.build_plan(seeds=seeds, sweep_seeds=2, quick=quick).sweep.seeds == (100, 101)
    assert P.build_plan(seeds=[40, 41], quick=quick).sweep.seeds == (40, 41)
    budget = P.QUICK_SWEEP if quick else P.DEFAULT_SWEEP
    assert P.build_plan(seeds=2, quick=quick).sweep.seeds == tuple(range(budget.episodes))
    assert P.build_plan(quick=quick, sweep_seeds=3).sweep.seeds == (0, 1, 2)


def test_missing_ppo_policy(monkeypatch, tmp_path) -> None:
    gone = dataclasses.replace(catalog.CONTROLLERS["ppo"], policy=str(tmp_path / "none"))
    monkeypatch.setattr(catalog, "CONTROLLERS", {**catalog.CONTROLLERS, "ppo": gone})
    plan = P.build_plan()  # default run: a warning, and the others run
    assert "ppo" not in plan.controllers
    assert plan.controllers == [c for c in P.DEFAULT_CONTROLLERS if c != "ppo"]
    assert len(plan.notes) == 1 and str(tmp_path / "none") in plan.notes[0]
    with pytest.raises(P.BenchOptionError, match="--controllers ppo: .*none"):
        P.build_plan(controllers=["pi_kp1", "ppo"])  # asked for: an error
    with pytest.raises(P.BenchOptionError, match="--ppo-model: .*nowhere"):
        P.build_plan(ppo_model=tmp_path / "nowhere")


def test_default_and_quick_plans(monkeypatch) -> None:
    monkeypatch.setattr(catalog.ControllerRow, "policy_problem", lambda self: None)  # as if shipped
    plan = P.build_plan()
    assert plan.controllers == list(P.DEFAULT_CONTROLLERS) and plan.scenarios == list(P.DEFAULT_SCENARIOS)
    assert plan.wind_speeds_kmh == [10, 20, 30, 40, 50, 60, 70] and plan.threads == 1 and not plan.overwrite
    for s, b in P.DEFAULT_BUDGETS.items():
        r = plan.runs[s]
        assert r.steps == round(50 * b.seconds) and r.seeds == tuple(range(b.episodes))
        assert r.sequential == b.sequential and r.sequential_seeds == r.seeds[:b.sequential]
    # the hold figures rest on many episodes for the batched controllers, fewer for the MPC
    assert len(plan.runs["hold_front"].seeds) >= 64 and plan.runs["hold_front"].sequential >= 5
    assert plan.sweep_directions == ["front", "side"] and plan.env_kwargs == {}
    quick = P.build_plan(quick=True)
    assert len(quick.wind_speeds_kmh) < 5 and quick.sweep.steps < plan.sweep.steps
    for s in plan.scenarios:
        q, d = quick.runs[s], plan.runs[s]
        assert q.steps <= d.steps and len(q.seeds) < len(d.seeds)
    # explicit options win over --quick; --randomize; the sweep follows the hold scenarios
    p = P.build_plan(quick=True, seeds=2, steps=300, randomize=True, scenarios=["hold_side", "step"],
                     sequential_episodes=1, sweep_seeds=3)
    assert all(r.seeds == (0, 1) and r.steps == 300 and r.sequential == 1 for r in p.runs.values())
    assert p.sweep.steps == 300 and p.sweep.seeds == (0, 1, 2) and p.sweep.sequential == 1
    assert p.env_kwargs == {"randomize_params": True} and p.sweep_directions == ["side"]
    assert P.build_plan(scenarios=["step"]).sweep_directions == []
    assert P.build_plan(sweep=False).sweep_directions == []
    # from Python: an int is a count (--episodes), ints are the seeds, strings --seeds values
    assert P.build_plan(seeds=3).runs["step"].seeds == (0, 1, 2)
    assert P.build_plan(seeds=[4]).runs["step"].seeds == (4,)
    assert P.build_plan(seeds=["4"]).runs["step"].seeds == (4,)
    # a sweep point equal to a main scenario (same keys, length, warm-up) is taken from it
    same = P.build_plan(steps=300, wind_speeds=[40, 50])
    assert [pt[-1] for pt in sweep_points(same)] == [None, "hold_front", None, "hold_side"]
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


# ------------------------------------------------------------------ the output folder
@pytest.fixture
def no_work(monkeypatch) -> list:
    """Fails the test if the bench starts running."""
    started: list = []

    def run_plan(*a, **k):
        started.append(1)
        raise AssertionError("the bench started although --out is unusable")
    monkeypatch.setattr(B, "run_plan", run_plan)
    return started


def _one_line_error(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("dss14 bench: error: "), err
    for w in words:
        assert w in err, err
    return err


def test_out_is_a_file_fails_before_any_work(tmp_path, capsys, no_work) -> None:
    f = tmp_path / "results.txt"
    f.write_text("mine")
    assert cli.main(["bench", "--quick", "--out", str(f)]) == 2
    _one_line_error(capsys, "is a file")
    assert cli.main(["bench", "--quick", "--out", str(f / "sub")]) == 2
    _one_line_error(capsys, "cannot create")
    assert not no_work and f.read_text() == "mine"


def test_unwritable_out_fails_before_any_work(tmp_path, capsys, no_work, monkeypatch) -> None:
    """A folder the process cannot write into (simulated: the write probe is refused, as for a
    read-only mount or another user's folder; a permission bit would not stop root)."""
    import tempfile

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    d = tmp_path / "locked"
    d.mkdir()
    monkeypatch.setattr(tempfile, "mkstemp", refused)
    assert cli.main(["bench", "--quick", "--out", str(d)]) == 2
    _one_line_error(capsys, "not writable")
    assert not no_work and list(d.iterdir()) == []


def test_a_used_folder_is_refused_unless_overwrite(tmp_path, capsys, monkeypatch) -> None:
    out = tmp_path / "out"
    prepare_output_dir(out, B.OWNED_FILES, command=B.COMMAND)  # an earlier bench: its files listed
    for name in ("results.json", "results.md", F.FIGURES[1]):
        atomic_write_text(out / name, "old")
    update_manifest(out)
    for name in ("mine.png", "notes.txt"):  # the user's, written after
        (out / name).write_text("old")
    started: list = []
    monkeypatch.setattr(B, "run_plan", lambda *a, **k: started.append(1) or (_ for _ in ()).throw(
        RuntimeError("stop here")))
    assert cli.main(["bench", "--quick", "--out", str(out)]) == 2
    _one_line_error(capsys, "already holds results", "--overwrite")
    assert not started and (out / "results.json").read_text() == "old"
    # --overwrite clears exactly what the bench owns, then the run starts
    assert cli.main(["bench", "--quick", "--out", str(out), "--overwrite"]) == 2
    assert started and "stop here" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "mine.png", "notes.txt"]


# ------------------------------------------------------------------ a tiny run
@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("bench") / "out"
    plan = P.build_plan(controllers=CTRLS, scenarios=SCENS, seeds=SEEDS, steps=STEPS,
                        sequential_episodes=SEQ, sweep_seeds=2, wind_speeds=["40", "50"], out=out)
    res = B.bench(plan, progress=False)
    return {"plan": plan, "res": res, "out": out,
            "json": json.loads((out / "results.json").read_text())}


def _comparable(summary: dict) -> str:
    """A runner summary without the wall-clock figures, as JSON (NaN, e.g. a move not settled
    within the episode, equal to NaN)."""
    return json.dumps({k: v for k, v in summary.items() if k != "controller_time_ms"}, sort_keys=True)


def test_results_json_matches_the_runner(tiny) -> None:
    js = tiny["json"]
    with blas_threads(1):  # the bench's setting (the last bits of BLAS sums depend on it)
        direct = runner.run(CTRLS, SCENS, range(SEEDS), steps=STEPS, sequential_seeds=SEQ)
    assert js["meta"]["controllers"] == CTRLS and js["meta"]["scenarios"] == SCENS
    for c in CTRLS:
        for s in SCENS:
            assert _comparable(js["summary"][c][s]) == _comparable(direct["summary"][c][s]), (c, s)
    assert js["yardstick"] == direct["yardstick"] and set(js["yardstick"]) == {"hold_side"}


def test_every_figure_carries_its_interval(tiny) -> None:
    s = tiny["json"]["summary"]
    for c in CTRLS:
        cell = s[c]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]
        assert set(cell) >= {"value", "ci95", "n_episodes", "seconds"}
        lo, hi = cell["ci95"]
        assert lo < cell["value"] < hi
        batched = tiny["json"]["meta"]["batched"][c]
        assert batched == (c != "mpc")
        n = SEEDS if batched else SEQ  # the MPC, one at a time: the first seeds
        assert cell["n_episodes"] == n and cell["seconds"] == pytest.approx(n * (STEPS / 50 - 5.0))
        assert s[c]["step"]["step"]["az"]["overshoot_pct"]["ci95"][0] <= \
            s[c]["step"]["step"]["az"]["overshoot_pct"]["value"]
    r = s["pi_kp0.7"]["hold_side"]["vs_reference"]["az"]
    assert r["ci95"][0] <= r["value"] <= r["ci95"][1] and isinstance(r["significant"], bool)
    assert tiny["json"]["meta"]["reference"] == "pi_kp1"


def test_intervals_recomputed_from_the_stored_episodes(tiny) -> None:
    js = tiny["json"]
    rows = R.episode_rows(js["episodes"])
    assert len(rows) == 3 * 2 * SEEDS + 2 * SEQ and all("trace" not in ep for ep in rows)
    for c in CTRLS:
        for s in SCENS:
            eps = [ep for ep in rows if ep["controller"] == c and ep["scenario"] == s]
            again = runner.summarise(eps, runner.cell_rng(c, s))
            for ax in ("az", "el"):
                a = again["servo_error_mdeg"][ax]["three_sigma"]
                b = js["summary"][c][s]["servo_error_mdeg"][ax]["three_sigma"]
                # the stored values have 6 significant digits
                assert a["value"] == pytest.approx(b["value"], rel=1e-5)
                assert a["ci95"] == pytest.approx(b["ci95"], rel=1e-3)


def test_smoothness_of_every_controller_with_its_interval(tiny) -> None:
    """Acceleration-limit hits (% of steps) and the command change's share above 5 Hz (per
    axis) for every controller and scenario: the mean over the stored episodes with its
    interval, and both tables in results.md."""
    js = tiny["json"]
    rows = R.episode_rows(js["episodes"])
    for c in CTRLS:
        for s in SCENS:
            sm = js["summary"][c][s]["smoothness"]
            eps = [ep for ep in rows if ep["controller"] == c and ep["scenario"] == s]
            hits = [ep["smoothness"]["accel_limit_hits_pct"] for ep in eps]
            assert sm["accel_limit_hits_pct"]["value"] == pytest.approx(np.mean(hits), rel=1e-5, abs=1e-9)
            total = sum(ep["limit_hits"]["accel"] for ep in eps)
            assert np.mean(hits) == pytest.approx(100 * total / (len(eps) * STEPS), rel=1e-5)
            for ax in ("az", "el"):
                cell = sm["command_change_hf_pct"][ax]
                assert 0 <= cell["value"] <= 100 and cell["n_episodes"] == len(eps)
                if len(eps) > 1:
                    assert cell["ci95"][0] <= cell["value"] <= cell["ci95"][1]
    md = tiny["res"]["markdown"]
    assert "| accel-limit hits (% of steps) |" in md and "| command change above 5 Hz az / el (%) |" in md


def test_results_json_records_the_run(tiny) -> None:
    js = tiny["json"]
    b = js["bench"]
    assert b["config"]["controllers"] == CTRLS
    assert b["config"]["runs"]["step"]["seeds"] == list(range(SEEDS))
    assert b["config"]["runs"]["step"]["sequential_seeds"] == list(range(SEQ))
    assert {r["steps"] for r in b["config"]["runs"].values()} == {STEPS}
    assert b["wall_time_s"]["total"] > 0 and b["notes"] == []
    assert set(b["figures"]) == set(F.FIGURES) and b["blas_threads"]["threads"] == 1
    assert "load_average_start" in b["machine"] and b["machine"]["cpu_count"] >= 1
    assert {"python", "numpy", "scipy", "gymnasium", "stable-baselines3", "torch", "cvxpy",
            "dss14-env"} <= set(js["versions"])
    assert js["versions"]["numpy"] == np.__version__
    assert js["statistics"]["level"] == 0.95 and "bootstrap" in js["statistics"]["interval"]


def test_wind_sweep_matches_the_runner(tiny) -> None:
    sw = tiny["json"]["wind_sweep"]
    assert sw["speeds_kmh"] == [40.0, 50.0] and sw["directions"] == ["side"]
    # the 50 km/h point is the hold_side scenario itself (same episodes), 40 km/h is run
    assert sw["points"]["hold_side_50kmh"]["same_as"] == "hold_side"
    assert sw["points"]["hold_side_40kmh"]["same_as"] is None
    cur = sw["curves"]["side"]
    assert cur["axis"] == "az"
    main = tiny["json"]["summary"]
    with blas_threads(1):
        direct = runner.run(CTRLS, [("p", P.sweep_scenario("side", 40, STEPS))], [0, 1], sequential_seeds=SEQ)
    for c in CTRLS:
        cells = cur["three_sigma_mdeg"][c]
        assert cells[0] == direct["summary"][c]["p"]["servo_error_mdeg"]["az"]["three_sigma"]
        assert cells[1] == main[c]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]
    ref = cur["yardstick_three_sigma_mdeg"]
    assert ref[0] == pytest.approx(direct["yardstick"]["p"]["three_sigma_mdeg"][0])
    assert ref[1] == pytest.approx(tiny["json"]["yardstick"]["hold_side"]["three_sigma_mdeg"][0])
    assert ref[0] < ref[1]


def test_results_md(tiny) -> None:
    md = (tiny["out"] / "results.md").read_text()
    assert md == tiny["res"]["markdown"] == R.results_markdown(tiny["json"])  # from the JSON alone
    assert tiny["res"]["main_table"] in md and "## How to read it" in md
    for c in CTRLS:
        assert f"| {c} |" in md
    assert "yardstick (analytic)" in md and "## Commanded move: step" in md and "side wind, 3σ az" in md
    # the commanded move is scored by its response, not by the 3σ of the move itself
    assert "| step az / el" not in md and "| step el / xel" not in md
    step = tiny["json"]["summary"]["pi_kp1"]["step"]["step"]
    assert {"overshoot_pct", "settling_time_s", "peak_error_mdeg", "settled_rms_mdeg"} <= set(step["az"])
    assert R.fmt_ci(step["az"]["settled_rms_mdeg"]) in md
    assert "hold_side az ÷ pi_kp1" in md and "Precision of the hold figures" in md
    pi = tiny["json"]["summary"]["pi_kp1"]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]
    assert R.fmt_ci(pi) in md and " ± " in R.fmt_ci(pi)


def test_figures_are_pngs_drawn_without_pyplot(tiny) -> None:
    for f in F.FIGURES:
        p = tiny["out"] / f
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 5000, f
    # drawing from results.json in a fresh interpreter loads neither pyplot nor a backend switch
    code = ("import json, sys, pathlib; from dss14_env.bench import figures as F; "
            f"r = json.loads(pathlib.Path({str(tiny['out'] / 'results.json')!r}).read_text()); "
            f"d = pathlib.Path({str(tiny['out'])!r}) / 'again'; d.mkdir(); "
            "assert F.plot_error_bars(r, d / 'a.png') and F.plot_wind_sweep(r, d / 'b.png'); "
            "print('matplotlib.pyplot' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == "False", done.stderr
    assert "matplotlib.use(" not in Path(F.__file__).read_text()
    import shutil
    shutil.rmtree(tiny["out"] / "again")
    # no temporary files of the atomic writes are left behind
    assert sorted(p.name for p in tiny["out"].iterdir()) == sorted(R.RESULT_FILES + F.FIGURES + (MANIFEST,))


def test_traces_of_the_first_seed(tiny) -> None:
    eps = tiny["res"]["ran"]["main"]["episodes"]
    traced = [(e["controller"], e["scenario"], e["seed"]) for e in eps if "trace" in e]
    assert sorted(traced) == sorted((c, s, 0) for c in CTRLS for s in SCENS)
    step = next(e for e in eps if e["scenario"] == "step" and "trace" in e)
    tr = step["trace"]
    n = step["n_steps"]
    assert tr["t"].shape == (n,) and tr["t"][0] == pytest.approx(0.02)
    for k in ("servo_error_mdeg", "pointing_error_mdeg", "command_deg", "encoder_deg", "rate_command_deg_s"):
        assert tr[k].shape == (n, 2), k
    assert tr["command_deg"][-1] == pytest.approx([0.1, 0.1])
    # the metric's position (command - true error) and the encoder agree within a count or so
    pos = tr["command_deg"] - tr["servo_error_mdeg"] / 1e3
    assert np.max(np.abs(pos - tr["encoder_deg"])) < 1e-3


def test_an_episode_that_ends_before_the_step(tmp_path, capsys) -> None:
    # too short to score anything: refused before any work (every cell would be empty)
    with pytest.raises(P.BenchOptionError, match="--steps: 20 control periods .* give --steps 50"):
        P.build_plan(controllers=["pi_kp1"], scenarios=["step"], seeds=2, steps=20)
    assert cli.main(["bench", "--steps", "10", "--out", str(tmp_path / "x")]) == 2
    _one_line_error(capsys, "--steps")
    assert not (tmp_path / "x").exists()
    # a plan made from Python past the check still gives empty cells, not a crash
    plan = P.build_plan(controllers=["pi_kp1"], scenarios=["step"], seeds=2, steps=50, out=tmp_path / "o")
    plan = dataclasses.replace(plan, runs={"step": dataclasses.replace(plan.runs["step"], steps=20)})
    res = B.bench(plan, progress=False)
    st = res["results"]["summary"]["pi_kp1"]["step"]
    assert "step" not in st or np.isnan(st["step"]["az"]["overshoot_pct"]["value"])
    assert "| pi_kp1 | — / — |" in res["markdown"]


def test_the_ppo_entry_loads_the_policy_on_the_env(monkeypatch, tmp_path) -> None:
    import dss14_env.agents.policy
    from dss14_env.baselines.pi import PIController

    calls = []

    def fake_load(path=None, env=None, name=None):
        calls.append((path, env))
        return PIController(env)

    monkeypatch.setattr(catalog.ControllerRow, "policy_problem", lambda self: None)
    monkeypatch.setattr(dss14_env.agents.policy, "load_policy", fake_load)
    plan = P.build_plan(controllers=["ppo"], scenarios=["step"], seeds=["1"], steps=50,
                        out=tmp_path / "o", figures=False)
    res = B.bench(plan, progress=False)
    assert len(calls) == 1 and calls[0][0] == catalog.CONTROLLERS["ppo"].policy_path()
    assert calls[0][1] is not None
    assert set(res["results"]["summary"]) == {"ppo"} and "| ppo |" in res["markdown"]
    # a trained policy replaces the row and scores under its own name
    best = tmp_path / "myrun" / "eval" / "best"
    plan = P.build_plan(controllers=["pi_kp1", "ppo"], scenarios=["step"], seeds=["1"], steps=50,
                        ppo_model=best, out=tmp_path / "o2", figures=False)
    res = B.bench(plan, progress=False)
    assert calls[-1][0] == best and plan.controllers == ["pi_kp1", "myrun/best"]
    assert set(res["results"]["summary"]) == {"pi_kp1", "myrun/best"}
    assert res["results"]["bench"]["config"]["policies"] == {"myrun/best": str(best)}
    assert res["figures"] == [] and not (tmp_path / "o" / F.FIGURES[0]).exists()


# ------------------------------------------------------------------ formatting
@pytest.mark.parametrize("value,ci,text", [
    (2.7953, [2.735, 2.855], "2.80 ± 0.06"),
    (0.02931, [0.0282, 0.0304], "0.0293 ± 0.0011"),
    (165.2, [164.9, 165.5], "165.2 ± 0.3"),
    (0.5, [float("nan"), float("nan")], "0.500 (1 ep.)"),
    (9.88, [9.88, 9.88], "9.88 ± 0"),
    (0.2000000000000002, [0.2, 0.20000000000000004], "0.20000 ± 0.00000"),
    (float("inf"), [float("inf"), float("inf")], "∞"),
])
def test_values_are_shown_with_their_half_width(value, ci, text) -> None:
    assert R.fmt_ci({"value": value, "ci95": ci, "n_episodes": 1}) == text


@pytest.mark.parametrize("r,text", [
    ({"value": 0.187, "ci95": [0.180, 0.195], "significant": True}, "0.187 [0.180, 0.195]"),
    ({"value": 1.02, "ci95": [0.97, 1.06], "significant": False}, "1.02 [0.97, 1.06] n.s."),
])
def test_ratios_say_when_they_are_not_significant(r, text) -> None:
    assert R.fmt_ratio(r) == text


def test_fallbacks_are_listed_per_episode() -> None:
    res = {"episodes": {"mpc": {"hold_front": {
        "seed": [0, 1], "fallbacks": [0, 2],
        "fallback_log": [[], [{"step": 12, "status": "infeasible"},
                              {"step": 40, "status": "solver_error"}]]}}}}
    assert R.fallback_lines(res) == ["* mpc, hold_front, seed 1: 2 fallbacks (step 12: infeasible, "
                                     "step 40: solver_error)"]


# ------------------------------------------------------------------ the README's table
def _readme_region() -> str:
    text = (ROOT / "README.md").read_text()
    m = re.search(r"<!-- bench-headline:start -->\n(.*?)<!-- bench-headline:end -->", text, re.S)
    assert m, "README.md lacks the bench-headline markers"
    return m.group(1)


def test_readme_headline_is_generated_from_the_committed_default_results() -> None:
    results = json.loads(DEFAULT_RESULTS.read_text())
    assert _readme_region() == R.headline_table(results, "docs/results/bench_default.md"), \
        "README.md's headline differs from docs/results/bench_default.json: run scripts/readme_tables.py"
    full = (ROOT / "docs" / "results" / "bench_default.md").read_text()
    assert full == R.results_markdown(results), \
        "docs/results/bench_default.md differs from its results: run scripts/readme_tables.py"


def test_headline_is_the_loaded_pointing_axis_of_each_hold(tiny) -> None:
    """One row per controller: the hold's 3σ of the loaded pointing axis and its paired ratio to
    the PI, as stored in results.json, then one legend line naming the full tables."""
    js, head = tiny["json"], tiny["res"]["headline"]
    table, legend = head.rstrip("\n").split("\n\n")
    lines = table.split("\n")
    assert lines[0] == "| controller | hold_side xel 3σ (mdeg) | ÷ pi_kp1 |"  # hold_front did not run
    assert len(lines) == 2 + len(CTRLS) and "\n" not in legend
    assert legend.endswith(f"full tables: {tiny['out'] / 'results.md'}.")
    for c, line in zip(CTRLS, lines[2:], strict=True):
        cell = js["summary"][c]["hold_side"]
        ratio = "1" if c == "pi_kp1" else R.fmt_ratio(cell["vs_reference_pointing_error_mdeg"]["xel"])
        assert line == f"| {c} | {R.fmt_ci(cell['pointing_error_mdeg']['xel']['three_sigma'])} | {ratio} |"


def test_headline_of_the_default_run_shows_both_holds() -> None:
    results = json.loads(DEFAULT_RESULTS.read_text())
    head = R.headline_table(results)
    assert head.startswith("| controller | hold_front el 3σ (mdeg) | ÷ pi_kp1 | hold_side xel 3σ (mdeg) "
                           "| ÷ pi_kp1 |\n")
    assert head.count("\n| ") == len(results["meta"]["controllers"])  # a row each, below the rule
    assert "full tables: results.md." in head


def test_cli_bench_prints_the_headline_not_the_large_tables(monkeypatch, capsys, tmp_path) -> None:
    results = json.loads(DEFAULT_RESULTS.read_text())
    head = R.headline_table(results, str(tmp_path / "results.md"))
    fake = {"results": results, "headline": head, "pointing_table": R.pointing_table(results),
            "main_table": R.main_table(results), "figures": [], "wall_time_s": 1.0}
    monkeypatch.setattr(B, "bench", lambda plan, progress=True: fake)
    assert cli.main(["bench", "--quick", "--no-progress", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert head in out and fake["pointing_table"] not in out and fake["main_table"] not in out


def test_committed_results_are_a_default_run() -> None:
    results = json.loads(DEFAULT_RESULTS.read_text())
    cfg = results["bench"]["config"]
    assert not cfg["quick"] and cfg["env_kwargs"] == {} and cfg["threads"] == 1
    assert results["bench"]["command"].startswith("dss14 bench")
    for s, b in P.DEFAULT_BUDGETS.items():
        assert cfg["runs"][s]["seeds"] == list(range(b.episodes)), s
        assert cfg["runs"][s]["steps"] == round(50 * b.seconds), s
    assert results["meta"]["controllers"] == list(P.DEFAULT_CONTROLLERS)
    assert cfg["sweep"]["seeds"] == list(range(P.DEFAULT_SWEEP.episodes))
    assert cfg["wind_speeds_kmh"] == list(P.default_wind_speeds())
    # every batchable row acted on batches
    assert results["meta"]["batched"] == {c: catalog.CONTROLLERS[c].batchable for c in P.DEFAULT_CONTROLLERS}


def test_the_repositorys_generated_tables_are_current() -> None:
    """README.md and docs/bench.md: every generated region equals its rendering from the
    committed default results and the catalog."""
    done = _script("readme_tables.py", "--check")
    assert done.returncode == 0, done.stderr


def test_pointing_is_the_headline(tiny) -> None:
    """The dish's pointing error leads results.md, and its paired ratios to the PI are the
    pooled 3σ (root mean square over episodes) of the same seeds, recomputed here from the
    stored episodes."""
    md, js = tiny["res"]["markdown"], tiny["json"]
    assert md.index(tiny["res"]["pointing_table"]) < md.index(tiny["res"]["main_table"])
    assert md.index("true pointing error") < md.index("servo error at the drive encoders")
    # the pointing yardstick's analytic figure and the ratios to it, on the loaded pointing axis
    assert "| pointing yardstick (analytic) |" in md and "hold_side xel ÷ pointing yardstick" in md
    eps = {(e["controller"], e["scenario"], e["seed"]): e for e in R.episode_rows(js["episodes"])}
    for c in CTRLS:
        for s in SCENS:
            cell = js["summary"][c][s]
            assert R.fmt_ci(cell["pointing_error_mdeg"]["xel"]["three_sigma"]) in md
            r = cell["vs_reference_pointing_error_mdeg"]
            seeds = [k[2] for k in eps if k[:2] == (c, s)]
            for ax in ("el", "xel"):
                num = [eps[(c, s, k)]["pointing_error_mdeg"][ax]["three_sigma"] for k in seeds]
                den = [eps[("pi_kp1", s, k)]["pointing_error_mdeg"][ax]["three_sigma"] for k in seeds]
                expect = np.sqrt(np.mean(np.square(num))) / np.sqrt(np.mean(np.square(den)))
                assert r[ax]["value"] == pytest.approx(expect, rel=1e-5)  # 6-digit stored episodes
                assert r[ax]["n_episodes"] == len(seeds)
                lo, hi = r[ax]["ci95"]
                assert c == "pi_kp1" or lo <= r[ax]["value"] <= hi


def test_readme_script_checks_and_writes(tmp_path) -> None:
    readme, full = tmp_path / "README.md", tmp_path / "bench_default.md"
    readme.write_text("intro\n<!-- bench-headline:start -->\nSTALE-TABLE\n"
                      "<!-- bench-headline:end -->\nrest\n")
    script = ROOT / "scripts" / "readme_tables.py"
    cmd = [sys.executable, str(script), "--readme", str(readme), "--full-tables", str(full),
           "--results", str(DEFAULT_RESULTS)]
    assert subprocess.run(cmd + ["--check"], capture_output=True).returncode == 1
    assert not full.exists()
    assert subprocess.run(cmd, capture_output=True).returncode == 0
    assert subprocess.run(cmd + ["--check"], capture_output=True).returncode == 0
    text = readme.read_text()
    assert text.startswith("intro\n") and text.endswith("rest\n") and "STALE-TABLE" not in text
    results = json.loads(DEFAULT_RESULTS.read_text())
    assert full.read_text() == R.results_markdown(results)
    full.write_text(full.read_text() + "typed by hand\n")
    assert subprocess.run(cmd + ["--check"], capture_output=True).returncode == 1


def test_readme_script_requires_the_headline_region(tmp_path) -> None:
    readme = tmp_path / "README.md"
    readme.write_text("no generated table here\n")
    done = _script("readme_tables.py", "--check", "--readme", str(readme))
    assert done.returncode == 2 and "bench-headline" in done.stderr


# ------------------------------------------------------------------ the scripts
def _script(name: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "scripts" / name), *args], capture_output=True,
                          text=True)


def test_two_runs_are_compared_within_their_intervals(tiny, tmp_path) -> None:
    a = tiny["out"] / "results.json"
    same = _script("compare_bench_runs.py", str(a), str(a))
    assert same.returncode == 0 and same.stdout.count("0 (0.0 %) outside the other run's interval") == 3
    js = json.loads(a.read_text())
    cell = js["summary"]["pi_kp1"]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]
    cell["value"] = cell["ci95"][1] * 1.5  # far outside the first run's interval
    b = tmp_path / "b.json"
    b.write_text(json.dumps(js))
    moved = _script("compare_bench_runs.py", str(a), str(b))
    assert moved.returncode == 1 and "main/pi_kp1/hold_side/servo_error_mdeg/az/three_sigma" in moved.stdout
    js["bench"]["config"]["runs"]["step"]["steps"] = 10
    b.write_text(json.dumps(js))
    assert _script("compare_bench_runs.py", str(a), str(b)).returncode == 2


@pytest.mark.parametrize("script,args", [
    ("compare_bench_runs.py", ["/nonexistent/a.json", "/nonexistent/b.json"]),
    ("bench_targets.py", ["/nonexistent/results.json"]),
    ("readme_tables.py", ["--check", "--results", "/nonexistent/r.json"])])
def test_scripts_name_a_missing_file_in_one_line(script, args) -> None:
    done = _script(script, *args)
    assert done.returncode == 2 and "/nonexistent/" in done.stderr and "Traceback" not in done.stderr
    assert done.stderr.strip().count("\n") == 0


def test_targets_script_reads_a_run(tiny) -> None:
    done = _script("bench_targets.py", str(tiny["out"] / "results.json"))
    assert "wall time" in done.stdout and "of 300 s" in done.stdout
    # 4 episodes with 1 s of data each: far from the 5 % precision target
    assert done.returncode == 1 and "hold_side az    pi_kp1" in done.stdout and "MISSED" in done.stdout


# ------------------------------------------------------------------ end to end
def test_cli_quick_end_to_end(tmp_path, capsys) -> None:
    """``dss14 bench --quick``, the CI smoke test: every default controller and scenario."""
    out = tmp_path / "q"
    assert cli.main(["bench", "--quick", "--no-progress", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| mpc |" in text and "written to" in text and " ± " in text
    js = json.loads((out / "results.json").read_text())
    assert js["meta"]["scenarios"] == list(P.DEFAULT_SCENARIOS)
    assert js["bench"]["command"].startswith("dss14 bench --quick")
    assert sum(v["failures"] for c in js["summary"].values() for v in c.values()) == 0
    # plain PPO, trained in holds only, leaves the error bound in slews (docs/rl.md); the
    # designed controllers and the residual agents never terminate
    assert sum(v["terminated"] for name, c in js["summary"].items() if name != "ppo_plain"
               for v in c.values()) == 0
    for f in ("results.md",) + F.FIGURES:
        assert (out / f).stat().st_size > 0, f
    # a second run into the same folder is refused
    assert cli.main(["bench", "--quick", "--out", str(out)]) == 2


def test_blas_threads_limits_and_restores() -> None:
    import scipy.linalg  # noqa: F401  (its OpenBLAS loaded, as blas_threads does)
    from threadpoolctl import threadpool_info

    def blas() -> list[int]:
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    before = blas()
    with blas_threads(1) as bt:
        assert bt.n_libraries == len(before) >= 1 and blas() == [1] * len(before)
    assert blas() == before
    with blas_threads(None) as bt:
        assert bt.n_libraries == 0 and blas() == before


def test_variants_option() -> None:
    assert P.build_plan().variants == list(P.DEFAULT_VARIANTS)
    assert P.build_plan(quick=True).variants == []  # the smoke run builds no other model
    assert P.build_plan(variants=[]).variants == []
    assert P.build_plan(variants=["stiff"]).variants == ["stiff"]
    with pytest.raises(P.BenchOptionError, match="--variants"):
        P.build_plan(variants=["stiffest"])
    # the variants run the hold scenarios with the PI and the LQGs, nothing else
    p = P.build_plan(variants=["soft"], scenarios=["step"])
    assert p.variants == [] and any("--variants ignored" in n for n in p.notes)
    assert P.build_plan(controllers=["mpc"]).variants == []


def test_the_drive_variants_run_beside_the_nominal_model(tiny) -> None:
    dv = tiny["json"]["drive_variants"]
    assert dv["variants"] == list(P.DEFAULT_VARIANTS) and dv["scenarios"] == ["hold_side"]
    assert dv["meta"]["controllers"] == ["pi_kp1", "lqg"]  # those of VARIANT_CONTROLLERS that ran
    names = [f"hold_side@{v}" for v in P.DEFAULT_VARIANTS]
    assert list(dv["summary"]["pi_kp1"]) == names
    # each variant's yardstick is its own model's: the stiff drive needs the strongest loads
    point = {s: y["pointing"]["pointing_three_sigma_mdeg"][1]
             for s, y in {**dv["yardstick"], "hold_side": tiny["json"]["yardstick"]["hold_side"]}.items()}
    assert point["hold_side@soft"] < point["hold_side"] < point["hold_side@stiff"]
    md = (tiny["out"] / "results.md").read_text()
    assert "drive/structure split" in md and "hold_side@stiff" in md


def _numbers(results: dict) -> str:
    """A results.json's figures and episodes, without the wall-clock and run records."""
    drop = {"controller_time_ms", "wall_time_s", "controller_wall_time_s", "created_utc", "bench",
            "load_average_start", "load_average_end"}

    def strip(x):
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items()
                    if k not in drop and not k.startswith("controller_time_ms")}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x
    return json.dumps(strip(results), sort_keys=True)


def test_jobs_give_the_serial_runs_numbers(tmp_path) -> None:
    """Worker processes run the scenarios and sweep points side by side: same numbers."""
    runs = {}
    for jobs in (1, 2):
        plan = P.build_plan(controllers=["pi_kp1", "lqg", "mpc"], scenarios=["hold_side", "step"], seeds=3,
                            steps=300, sequential_episodes=1, sweep_seeds=2, wind_speeds=["40", "50"],
                            out=tmp_path / str(jobs), figures=False, jobs=jobs)
        assert plan.jobs == jobs
        res = B.bench(plan, progress=False)
        runs[jobs] = json.loads((tmp_path / str(jobs) / "results.json").read_text())
        assert res["results"]["bench"]["config"]["jobs"] == jobs
    assert "pool" in runs[2]["bench"]["wall_time_s"] and "pool" not in runs[1]["bench"]["wall_time_s"]
    assert runs[1]["summary"]["mpc"]["hold_side"]["servo_error_mdeg"]["el"]["three_sigma"]["n_episodes"] == 1
    assert _numbers(runs[1]) == _numbers(runs[2])


@pytest.mark.parametrize("jobs", [0, -1, "x"])
def test_bad_jobs_are_named(jobs) -> None:
    with pytest.raises(P.BenchOptionError, match="^--jobs"):
        P.build_plan(controllers=["pi_kp1"], scenarios=["step"], quick=True, jobs=jobs)


def test_default_jobs_are_the_usable_cpus() -> None:
    assert P.build_plan(controllers=["pi_kp1"], scenarios=["step"], quick=True).jobs == P.default_jobs()
    assert 1 <= P.default_jobs() <= min(P.MAX_DEFAULT_JOBS, os.cpu_count() or 1)



def _worker_handlers(plan, conn) -> None:
    from dss14_env.bench import run as bench_run
    from dss14_env.core.stop import terminate_as_interrupt

    with terminate_as_interrupt():  # as the command runs the bench
        bench_run._init_worker(plan)
        conn.send((signal.getsignal(signal.SIGTERM) == signal.SIG_DFL,
                   signal.getsignal(signal.SIGINT) == signal.SIG_IGN))


@pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="the pool forks")
def test_a_worker_ends_quietly_on_the_pools_sigterm() -> None:
    """The pool ends its workers with SIGTERM when the run is over: a worker forked from the
    command (whose SIGTERM handler raises) must die quietly, not print a traceback; Ctrl-C is the
    parent's."""
    plan = P.build_plan(controllers=["pi_kp1"], scenarios=["step"], quick=True, jobs=2)
    ctx = multiprocessing.get_context("fork")
    parent, child = ctx.Pipe()
    p = ctx.Process(target=_worker_handlers, args=(plan, child))
    p.start()
    assert parent.recv() == (True, True)
    p.join(30)
