"""The learned agents' results (agents/results.py, scripts/rl_results.py): the statistics, the
committed results file against the shipped policies, and the docs/results/rl_results.md tables as its
rendering (nothing typed by hand)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from dss14_env.agents.evaluation import DSS14_TASKS, FINAL_SCORING, run_task
from dss14_env.agents.policy import load_policy, shipped_policies
from dss14_env.agents.results import agent_ratio, build_results, rl_tables

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results" / "rl_results.json"


def _summary(x_front: np.ndarray, x_side: np.ndarray, test_seeds: list[int],
             pointing: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """A campaign summary with the given (training seeds, test seeds) 3σ (and pointing 3σ)."""
    per_seed = []
    for k in range(x_front.shape[0]):
        res = {"hold_front": {"three_sigma_mdeg": x_front[k].tolist()},
               "hold_side": {"three_sigma_mdeg": x_side[k].tolist()}}
        if pointing is not None:
            for hold, p in zip(("hold_front", "hold_side"), pointing, strict=True):
                res[hold]["pointing_three_sigma_mdeg"] = p[k].tolist()
        per_seed.append({"seed_index": k, "wall_s": 10.0, "env_steps": 1000,
                         "final": res, "best": res})
    return {"algo": "ppo", "env_id": "DSS14-Plain-v0", "config": "x.yaml",
            "training_seeds": [10_000 + 1000 * k for k in range(x_front.shape[0])],
            "protocol": {"test_seeds": test_seeds}, "per_seed": per_seed}


def _iqm5(v: np.ndarray) -> float:
    """The interquartile mean of 5 values: 25 % trimmed from each end, i.e. the middle 3."""
    return float(np.sort(v)[1:4].mean())


def test_agent_ratio_value_and_interval() -> None:
    rng = np.random.default_rng(1)
    ref = rng.uniform(1.0, 3.0, 10)
    x = ref[None, :] * rng.uniform(0.4, 0.6, (5, 1))  # every seed about half the reference
    r = agent_ratio(x, ref, np.random.default_rng(0))
    assert r["value"] == pytest.approx(_iqm5(x.mean(axis=1)) / ref.mean())
    lo, hi = r["ci95"]
    assert lo <= r["value"] <= hi and hi < 1.0 and r["significant"]
    same = agent_ratio(np.tile(ref, (5, 1)) * rng.uniform(0.9, 1.1, (5, 10)), ref,
                       np.random.default_rng(0))
    assert same["ci95"][0] < 1.0 < same["ci95"][1] and not same["significant"]
    with pytest.raises(ValueError, match="agent_ratio"):
        agent_ratio(x[:, :9], ref, np.random.default_rng(0))


def test_build_results_rows_and_seed_check() -> None:
    rng = np.random.default_rng(2)
    seeds = list(range(10))
    refs = {"pi_kp1": ("PI", {"hold_front": rng.uniform(2, 3, 10).tolist(),
                              "hold_side": rng.uniform(1.5, 2.5, 10).tolist()}),
            "lqg": ("LQG", {"hold_front": rng.uniform(0.4, 0.5, 10).tolist(),
                            "hold_side": rng.uniform(0.2, 0.3, 10).tolist()})}
    xf, xs = rng.uniform(1, 2, (5, 10)), rng.uniform(1, 2, (5, 10))
    res = build_results({"a": ("agent", _summary(xf, xs, seeds), {})}, refs, seeds)
    row = res["rows"]["a"]
    assert row["holds"]["hold_front"]["per_seed"] == pytest.approx(xf.mean(axis=1).tolist())
    assert row["holds"]["hold_front"]["iqm"]["value"] == pytest.approx(_iqm5(xf.mean(axis=1)))
    pi = res["rows"]["pi_kp1"]["holds"]["hold_side"]
    assert pi["mean"]["value"] == pytest.approx(np.mean(refs["pi_kp1"][1]["hold_side"]))
    assert pi["ratios"]["pi_kp1"]["value"] == pytest.approx(1.0)
    tables = rl_tables(res)
    assert "| agent | 5 × 10 |" in tables["rl-table"]
    assert tables["rl-seeds"].count("\n| agent | 1") == 5  # one row per training seed
    assert json.loads(json.dumps(res)) == res  # JSON-ready
    with pytest.raises(ValueError, match="test seeds"):
        build_results({"a": ("agent", _summary(xf, xs, seeds), {})}, refs, list(range(1, 11)))


def test_pointing_columns_of_agents_references_and_bounds() -> None:
    """Pointing entries come from the summaries' pointing scores and divide by the references'
    pointing errors; an agent or reference without them shows "–" in the pointing table only."""
    rng = np.random.default_rng(3)
    seeds = list(range(10))

    def holds(lo: float, hi: float) -> dict:
        return {h: rng.uniform(lo, hi, 10).tolist() for h in ("hold_front", "hold_side")}

    refs = {"pi_kp1": ("PI", holds(2, 3), holds(3, 4)), "lqg": ("LQG", holds(0.4, 0.5), holds(2.5, 4.5)),
            "mpc": ("MPC", holds(0.4, 0.5)), "lqg_pointing": ("pointing LQG", None, holds(1, 2))}
    xf, xs = rng.uniform(1, 2, (5, 10)), rng.uniform(1, 2, (5, 10))
    pf, ps = rng.uniform(2, 3, (5, 10)), rng.uniform(2, 3, (5, 10))
    res = build_results({"p": ("pointing agent", _summary(xf, xs, seeds, (pf, ps)), {}),
                         "s": ("servo agent", _summary(xf, xs, seeds), {})}, refs, seeds,
                        analytic={"bound": ("bound", None, {"hold_front": 1.0, "hold_side": 0.5})})
    d = res["rows"]["p"]["holds"]["hold_side"]["pointing"]
    assert d["axis"] == "xel" and d["iqm"]["value"] == pytest.approx(_iqm5(ps.mean(axis=1)))
    assert d["ratios"]["pi_kp1"]["value"] == pytest.approx(
        _iqm5(ps.mean(axis=1)) / np.mean(refs["pi_kp1"][2]["hold_side"]))
    # the servo entry is the same with and without pointing scores (own resampling streams)
    sp, ss = (res["rows"][k]["holds"]["hold_side"] for k in ("p", "s"))
    assert sp["per_seed"] == ss["per_seed"] and sp["iqm"]["value"] == ss["iqm"]["value"]
    assert "pointing" not in res["rows"]["s"]["holds"]["hold_side"]
    lp = res["rows"]["lqg_pointing"]["holds"]["hold_front"]
    assert "mean" not in lp and lp["pointing"]["ratios"]["lqg"]["value"] == pytest.approx(
        np.mean(refs["lqg_pointing"][2]["hold_front"]) / np.mean(refs["lqg"][2]["hold_front"]))
    assert res["rows"]["bound"]["holds"]["hold_side"]["pointing"]["value"] == 0.5
    table = rl_tables(res)["rl-table"]
    pointing, servo = table.split("**Servo error**")
    line = {r.split(" | ")[0]: r for r in pointing.splitlines() if r.startswith("| ")}
    # 2 holds x (score + ratios to PI, LQG and the pointing LQG): 8 cells "–" where not measured
    assert line["| servo agent"].count("| – ") == 8 and "**" in line["| pointing agent"]
    assert line["| MPC"].count("| – ") == 8 and line["| LQG"].count("| – ") == 0
    sline = {r.split(" | ")[0]: r for r in servo.splitlines() if r.startswith("| ")}
    # the pointing LQG has no servo values: no servo ratio to it either
    assert sline["| pointing LQG"].count("| – ") == 8 and sline["| servo agent"].count("| – ") == 2
    seeds_rows = [r.split(" | ") for r in rl_tables(res)["rl-seeds"].splitlines()]
    assert all(r[2] != "–" and r[3] != "–" for r in seeds_rows if r[0] == "| pointing agent")
    assert all(r[2] == "–" and r[4] != "–" for r in seeds_rows if r[0] == "| servo agent")


# ------------------------------------------------------------------------------ committed results
@pytest.fixture(scope="module")
def results() -> dict:
    return json.loads(RESULTS.read_text())


def test_documents_show_the_committed_results() -> None:
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "rl_results.py"), "render",
                        "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_committed_results_follow_the_protocol(results: dict) -> None:
    assert results["test_seeds"] == list(range(10))
    # the agents trained on the beam and the references carry the pointing error
    for key in ("ppo_plain_pointing", "ppo_residual_lqg_pointing", "pi_kp1", "lqg", "lqg_pointing"):
        assert all("pointing" in results["rows"][key]["holds"][h] for h in ("hold_front", "hold_side")), key
    for key, row in results["rows"].items():
        if row["kind"] != "agent":
            continue
        assert len(row["training_seeds"]) >= 5, key
        assert min(row["training_seeds"]) >= 10_000 and row["scored_policy"] == "best"
        for hold in ("hold_front", "hold_side"):
            for h in (row["holds"][hold], row["holds"][hold].get("pointing")):
                if h is None:
                    continue
                assert len(h["per_seed"]) == len(row["training_seeds"])
                assert np.asarray(h["per_test_seed"]).shape == (len(row["training_seeds"]), 10)
                lo, hi = h["iqm"]["ci95"]
                assert lo <= h["iqm"]["value"] <= hi
                assert {"pi_kp1", "lqg"} <= set(h["ratios"]), key
                for ratio in h["ratios"].values():
                    assert ratio["significant"] == (not ratio["ci95"][0] <= 1.0 <= ratio["ci95"][1])


#: the general recipe's reports, one per version (rl_recipe.json, rl_recipe2.json, ...)
RECIPE_REPORTS = sorted((ROOT / "docs" / "results").glob("rl_recipe*.json"))
STALE = ROOT / "docs" / "results" / "rl_stale.json"


def _recipe() -> dict:
    """The recipe report whose policy the shipped folder holds: the one report with a ``shipped``
    entry (scripts/rl_results.py ship-recipe moves the others' to ``shipped_before``)."""
    claims = [r for r in (json.loads(p.read_text()) for p in RECIPE_REPORTS) if "shipped" in r]
    assert len(claims) == 1, f"{len(claims)} recipe reports claim the shipped folder"
    return claims[0]


def _shipped(results: dict) -> list[tuple[str, dict]]:
    """The results file's shipped rows whose folder still holds their policy (the shipping
    recipe report names the folder its shipped policy took)."""
    taken = {_recipe()["shipped"]["folder"]} if RECIPE_REPORTS else set()
    return [(k, row) for k, row in results["rows"].items()
            if row.get("shipped") and row["shipped"]["folder"] not in taken]


def test_the_recipes_shipped_policy_is_its_best_validation_seed() -> None:
    """The general recipe ships the seed with the best validation score (never chosen on the
    test seeds); the folder holds that seed's configuration."""
    rep = _recipe()
    shipped = rep["shipped"]
    cfg = yaml.safe_load((ROOT / shipped["folder"] / "config.yaml").read_text())
    assert cfg["seed"] == shipped["training_seed"]
    best = max(rep["per_seed"], key=lambda r: r["validation_score"])
    assert best["seed_index"] == shipped["seed_index"] == rep["shipped_seed_index"]
    assert len(rep["per_seed"]) >= 10


@pytest.mark.slow
def test_regression_shipped_policies_recipe_reproduces_its_test_scores(check_rescored) -> None:
    """Regression check: the general recipe's shipped policy, scored again on the test seeds,
    gives its campaign's hold figures recorded in its report (servo and pointing) within the
    scatter between CPU kinds (``tests/conftest.py``)."""
    rep = _recipe()
    ctrl = load_policy(ROOT / rep["shipped"]["folder"])
    groups = {}
    for task in DSS14_TASKS:
        got = run_task(ctrl, task, rep["protocol"]["test_seeds"], rep["protocol"]["test_steps"],
                       access=FINAL_SCORING)
        want = rep["shipped"]["holds"][task.name]
        groups[task.name] = (got["three_sigma_mdeg"], want["per_test_seed"])
        groups[f"{task.name} pointing"] = (got["pointing_three_sigma_mdeg"],
                                           want["pointing"]["per_test_seed"])
    check_rescored(groups)


def test_every_shipped_policy_is_a_campaign_seed_chosen_on_validation(results: dict) -> None:
    shipped = _shipped(results)
    assert {Path(row["shipped"]["folder"]).name for _, row in shipped} <= set(shipped_policies())
    assert {"ppo_plain", "ppo_residual_lqg"} <= {k for k, _ in shipped}
    for key, row in shipped:
        folder = ROOT / row["shipped"]["folder"]
        cfg = yaml.safe_load((folder / "config.yaml").read_text())
        assert cfg["seed"] == row["shipped"]["training_seed"], key
        i = row["training_seeds"].index(cfg["seed"])
        assert row["validation_score"][i] == max(row["validation_score"]), key


@pytest.mark.slow
def test_regression_shipped_policies_reproduce_their_test_scores(results: dict, check_rescored) -> None:
    """Regression check: every shipped folder, scored again on the test seeds, gives the results
    file's numbers -- its campaign row's, or, when that row is kept from earlier results (scored
    on the code of its time), the shipped policy's own row (``<key>_shipped``, scored when the
    file was built), servo and pointing errors -- within the scatter between CPU kinds
    (``tests/conftest.py``); a policy marked stale (trained on the earlier drive) against its
    re-scoring on the shipped drive (``rl_stale.json``, ``scripts/rl_results.py stale``)."""
    shipped = _shipped(results)
    assert shipped
    stale = json.loads(STALE.read_text())["rows"] if STALE.is_file() else {}
    groups = {}
    for key, row in shipped:
        ctrl = load_policy(ROOT / row["shipped"]["folder"])
        if key in stale:
            want = stale[key]["holds"]
            pick = {t.name: (want[t.name]["per_test_seed"], want[t.name]["pointing"]["per_test_seed"])
                    for t in DSS14_TASKS}
        elif row.get("kept_from"):
            want = results["rows"][f"{key}_shipped"]["holds"]
            pick = {t.name: (want[t.name]["per_test_seed"], want[t.name]["pointing"]["per_test_seed"])
                    for t in DSS14_TASKS}
        else:
            i = row["training_seeds"].index(row["shipped"]["training_seed"])
            h = row["holds"]
            pick = {t.name: (h[t.name]["per_test_seed"][i],
                             h[t.name]["pointing"]["per_test_seed"][i] if "pointing" in h[t.name] else None)
                    for t in DSS14_TASKS}
        for task in DSS14_TASKS:
            got = run_task(ctrl, task, results["test_seeds"], 3000, access=FINAL_SCORING)
            servo, pointing = pick[task.name]
            groups[f"{key} {task.name}"] = (got["three_sigma_mdeg"], servo)
            if pointing is not None:
                groups[f"{key} {task.name} pointing"] = (got["pointing_three_sigma_mdeg"], pointing)
    check_rescored(groups)
