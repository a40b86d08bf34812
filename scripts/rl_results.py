"""The learned agents' results: reference runs, the committed results file, its tables.

Three steps, each writing what the next reads::

    # 1. the reference controllers on the test seeds (the benchmark's runner; ~5 min on one core):
    #    3σ servo and pointing errors
    python scripts/rl_results.py references            # -> docs/results/rl_references.json
    #    the PI and LQG in the track, 0.1 deg step and 5 deg slew (the tracking, step and slew
    #    table's references; seconds)
    python scripts/rl_results.py scenario-references   # -> docs/results/rl_scenario_references.json
    # 2. the training campaigns (dss14 train <algo> --config <cfg> --train-seeds 0-4 --out runs/<agent>),
    #    then the results file and the learning-curve figures
    python scripts/rl_results.py build --runs runs  # -> docs/results/rl_results.json, rl/*.png
    #    (an agent whose campaign is not under --runs keeps its row of the committed file,
    #    marked kept_from: servo error only, the trained runs of those campaigns are not kept)
    # 3. the shipped policies: each shipped agent's seed with the best validation score
    python scripts/rl_results.py ship --runs runs      # -> agents/policies/<name>/
    # 4. the tables of docs/results/rl_results.md (rendered from the results file, never typed)
    python scripts/rl_results.py render                # rewrite them
    python scripts/rl_results.py render --check        # exit 1 if a document is out of date

The general recipe's many-seed reports (one results file per version: configs/ppo_general_lqg.yaml
-> rl_recipe.json, configs/ppo_general_lqg2.yaml -> rl_recipe2.json, configs/ppo_general_lqg3.yaml
-> rl_recipe3.json and its tables in rl_recipe3.md)::

    dss14 train ppo --config ppo_general_lqg2 --train-seeds 0-9 --out runs/ppo_general_lqg2
    python scripts/rl_results.py recipe --campaign runs/ppo_general_lqg2 --out docs/results/rl_recipe2.json
    python scripts/rl_results.py ship-recipe --campaign runs/ppo_general_lqg2 \
        --report docs/results/rl_recipe2.json   # its best-validation seed (the other report's
                                                # shipped entry becomes its shipped_before)
    python scripts/rl_results.py grid      # the shipped policy on the wind grid (its report)
    python scripts/rl_results.py grid --report docs/results/rl_recipe3.json \
        --campaign runs/ppo_general_lqg3   # a report's best-validation seed, shipped or not
    python scripts/rl_results.py render    # their tables too (blocks rl-recipe, rl-recipe2, rl-recipe3)

(tests/test_agents_results.py runs the check.)  The statistics are those of
:mod:`dss14_env.agents.results`.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from dss14_env.agents.campaign import selected_evaluation
from dss14_env.agents.results import HOLDS, POINTING_AXES, build_results, has_pointing, rl_tables
from dss14_env.core.arrays import read_arrays

ROOT = Path(__file__).resolve().parents[1]

RESULTS = ROOT / "docs" / "results" / "rl_results.json"
REFERENCES = ROOT / "docs" / "results" / "rl_references.json"
SCENARIO_REFERENCES = ROOT / "docs" / "results" / "rl_scenario_references.json"
FIGURES = ROOT / "docs" / "results" / "rl"
#: the generated blocks and the documents that show them
DOCUMENTS = {ROOT / "docs" / "results" / "rl_results.md": ("rl-table", "rl-seeds", "rl-campaign",
                                                           "rl-recipe", "rl-recipe2", "rl-recipe3")}
#: the robustness campaign of the learned policies beside PI and LQG (``dss14 campaign``,
#: :func:`dss14_env.bench.campaign_report.compact_results` of its results.json), and the command
CAMPAIGN = ROOT / "docs" / "results" / "campaign_policies.json"
#: the general recipe's report (:mod:`dss14_env.agents.recipe_report`), its shipped folder and
#: the wind grid it is checked on: (speed km/h, direction deg)
RECIPE = ROOT / "docs" / "results" / "rl_recipe.json"
#: every version's report, by the generated block that tables it
RECIPE_REPORTS = {"rl-recipe": RECIPE, "rl-recipe2": ROOT / "docs" / "results" / "rl_recipe2.json",
                  "rl-recipe3": ROOT / "docs" / "results" / "rl_recipe3.json"}
RECIPE_SHIPPED = "ppo_general"
RECIPE_GRID = tuple((50.0, d) for d in (0.0, 45.0, 90.0, 135.0, 180.0)) + tuple(
    (v, d) for v in (10.0, 70.0) for d in (0.0, 90.0))
RECIPE_GRID_STEPS = 1500
#: the shipped policies trained on the drive before the settled one, re-scored on it
STALE = ROOT / "docs" / "results" / "rl_stale.json"
#: the reference controllers: runner name -> label
REFERENCE_CONTROLLERS = {"pi_kp1": "PI (report: kp 1, ki 0.3)", "lqg": "LQG", "mpc": "MPC",
                         "yardstick": "yardstick (H2-optimal, knows the wind)"}
#: the references in the table: the yardstick's simulated run is kept in the references file
#: but not tabled (it is a bound of the linear model: under the plant's 0.2 deg/s^2
#: acceleration limit, which its design ignores, it saturates on some seeds -- front hold,
#: test seed 3: 2342 of 3000 steps at the limit, 245 mdeg); the table shows its analytic value
TABLE_REFERENCES = ("pi_kp1", "lqg", "mpc")
#: the pointing-aware references, run and tabled when the baselines provide them
POINTING_CONTROLLERS = {"lqg_pointing": "pointing-aware LQG", "mpc_pointing": "pointing-aware MPC"}
#: the agents: key -> (label, campaign folder under --runs, shipped policy folder or None)
AGENTS = {
    "ppo_plain": ("plain PPO", "ppo_plain", "ppo_plain"),
    "recurrent_ppo": ("recurrent PPO (LSTM)", "recurrent_ppo", None),
    "ppo_residual_lqg": ("model-informed PPO (residual on the LQG)", "ppo_residual_lqg",
                         "ppo_residual_lqg"),
    "sac": ("SAC", "sac", None),
    "ppo_residual_pi": ("residual PPO on the PI", "ppo_residual_pi", None),
    "ppo_residual_pi_hold": ("residual PPO on the PI, benchmark wind", "ppo_residual_pi_hold", None),
    # trained on the dish's true pointing error (reward: pointing, select_by: pointing)
    "ppo_plain_pointing": ("plain PPO, trained on the pointing error", "ppo_plain_pointing", None),
    "ppo_residual_lqg_pointing": ("model-informed PPO on the pointing LQG, trained on the pointing "
                                  "error", "ppo_residual_lqg_pointing", None),
    # one policy for the whole job (a mixture of every bench scenario, select_by general)
    # its shipped folder now holds the general recipe's policy (RECIPE, `ship-recipe`)
    "ppo_general": ("general plain PPO: one policy for tracks, holds, steps and slews", "ppo_general",
                    None),
    "ppo_general_random": ("general plain PPO trained on randomised plants", "ppo_general_random",
                           "ppo_general_random"),
}
#: single policies scored like the campaigns' (one training seed: an interval over test seeds
#: only): key -> (label, shipped folder, the agent whose campaign it is a seed of): a shipped
#: seed of a campaign gets its own row only while that campaign's row has no pointing scores
SINGLE_POLICIES = {
    "residual_pi_shipped": ("residual PPO on the PI, the policy shipped first (one training seed)",
                            "residual_pi", None),
    "ppo_plain_shipped": ("plain PPO, the shipped policy (its campaign's seed 11000)", "ppo_plain",
                          "ppo_plain"),
    "ppo_residual_lqg_shipped": ("model-informed PPO, the shipped policy (its campaign's seed "
                                 "10000)", "ppo_residual_lqg", "ppo_residual_lqg"),
}
TEST_SEEDS = list(range(10))



def ship_run(run: Path, dest: Path) -> None:
    """Copy a run's validation-selected policy (``eval/best``), its validation history and its
    training summary into the policy folder ``dest`` (replaced)."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for name in ("policy.pt", "normalization.npz", "config.yaml"):
        shutil.copyfile(run / "eval" / "best" / name, dest / name)
    shutil.copyfile(run / "eval" / "evaluations.npz", dest / "evaluations.npz")
    shutil.copyfile(run / "train_summary.json", dest / "train_summary.json")

def _machine() -> dict:
    return {"cpu_count": os.cpu_count(), "load_average": list(os.getloadavg()),
            "python": platform.python_version(), "platform": platform.platform()}


def _reference_controllers() -> dict[str, str]:
    """The reference controllers to run: :data:`REFERENCE_CONTROLLERS` and those of
    :data:`POINTING_CONTROLLERS` the installed baselines provide."""
    from dss14_env.bench.runner import CONTROLLERS

    known = set(CONTROLLERS)
    return {**REFERENCE_CONTROLLERS, **{k: v for k, v in POINTING_CONTROLLERS.items() if k in known}}


def references(out: Path) -> None:
    """Run the reference controllers on the test seeds of both holds (full 3000-step episodes):
    the 3σ servo error of the loaded axis and the 3σ pointing error of the swung axis."""
    from dss14_env.bench.runner import run

    labels = _reference_controllers()
    res = run(list(labels), list(HOLDS), TEST_SEEDS)
    values: dict[str, dict[str, list[float]]] = {
        c: {h: [float("nan")] * len(TEST_SEEDS) for h in HOLDS} for c in labels}
    pointing = {c: {h: [float("nan")] * len(TEST_SEEDS) for h in HOLDS} for c in labels}
    for e in res["episodes"]:
        if e["scenario"] in HOLDS:
            h, i = e["scenario"], TEST_SEEDS.index(e["seed"])
            values[e["controller"]][h][i] = e["servo_error_mdeg"][HOLDS[h]]["three_sigma"]
            pointing[e["controller"]][h][i] = e["pointing_error_mdeg"][POINTING_AXES[h]]["three_sigma"]
    yard = {h: y for h, y in (res.get("yardstick") or {}).items() if h in HOLDS and y}
    analytic = {h: y["three_sigma_mdeg"][0 if HOLDS[h] == "az" else 1] for h, y in yard.items()}
    # the yardstick's expected pointing 3σ ([el, xel]) and the pointing yardstick's expected
    # servo and pointing 3σ (its design scores the pointing error), where the runner has them
    analytic_p = _pointing_values(yard)
    pyard = {h: y["pointing"] for h, y in yard.items() if isinstance(y.get("pointing"), dict)}
    pointing_yardstick = None
    if len(pyard) == len(HOLDS) and len(_pointing_values(pyard)) == len(HOLDS):
        pointing_yardstick = {
            "three_sigma_mdeg": {h: y["three_sigma_mdeg"][0 if HOLDS[h] == "az" else 1]
                                 for h, y in pyard.items()},
            "pointing_three_sigma_mdeg": _pointing_values(pyard)}
    doc = {"what": "3-sigma servo error (mdeg) of the loaded axis and 3-sigma pointing error (mdeg) "
                   "of the swung axis (front: el, side: xel) per test seed, the benchmark's "
                   "runner (dss14_env.bench.runner.run), hold scenarios, 3000 steps, 5-s warm-up",
           "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "machine": _machine(), "test_seeds": TEST_SEEDS, "wall_time_s": res["meta"]["wall_time_s"],
           "labels": labels, "three_sigma_mdeg": values, "pointing_three_sigma_mdeg": pointing,
           "yardstick_analytic_three_sigma_mdeg": analytic,
           "yardstick_analytic_pointing_three_sigma_mdeg": analytic_p if len(analytic_p) == len(HOLDS)
           else None,
           "pointing_yardstick_analytic": pointing_yardstick}
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {out}")


def scenario_references(out: Path) -> None:
    """Score the campaigns' references (PI, LQG: dss14_env.agents.campaign_report.REFERENCES)
    on the test seeds of the track, step and slew, as a campaign scores its policies there (the
    bench's episodes, lengths and figures): the tracking, step and slew table's reference rows.
    """
    from dss14_env.agents.campaign_report import REFERENCES as CAMPAIGN_REFERENCES
    from dss14_env.agents.campaign_report import reference_scores
    from dss14_env.agents.evaluation import FINAL_SCORING, dss14_tasks
    from dss14_env.agents.results import SCENARIO_COLUMNS

    tasks = dss14_tasks(scenarios=list(SCENARIO_COLUMNS))
    scores = reference_scores(tasks, TEST_SEEDS, None, FINAL_SCORING)
    doc = {"what": "figures per test seed of the reference controllers in the track, step and slew "
                   "(dss14_env.agents.campaign_report.reference_scores: the bench's episode loop "
                   "and figures, the default bench run's episode lengths)",
           "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "machine": _machine(), "test_seeds": TEST_SEEDS,
           "steps": {t.name: t.steps for t in tasks},
           "labels": {k: CAMPAIGN_REFERENCES[k][0] for k in scores},
           "figures": {k: {scen: d["figures"] for scen, d in v.items()} for k, v in scores.items()}}
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {out}")


def _pointing_values(yard: dict) -> dict:
    """hold -> the expected 3σ pointing error of the hold's swung axis (``[el, xel]`` entries)."""
    return {h: y["pointing_three_sigma_mdeg"][0 if POINTING_AXES[h] == "el" else 1]
            for h, y in yard.items() if y.get("pointing_three_sigma_mdeg") is not None}


def _selected_at(run: Path) -> int | None:
    """The step of the validation-selected policy (the best selection score) of a run."""
    path = run / "eval" / "evaluations.npz"
    if not path.is_file():
        return None
    sel = selected_evaluation(path)
    if sel is None or not np.isfinite(sel[1][1]):
        return None  # no evaluation kept a policy: the final one is scored
    return int(read_arrays(path)["timesteps"][sel[0]])


def _best_validation(run: Path) -> tuple[bool, float]:
    """The rank of a run's selected evaluation: (beats the selection's reference, score)."""
    sel = selected_evaluation(run / "eval" / "evaluations.npz")
    return sel[1] if sel is not None else (False, -np.inf)


def _campaign(key: str, camp: Path, label: str, shipped: str | None) -> tuple[str, dict, dict]:
    """An agent's ``(label, summary, extra)`` from its campaign folder."""
    summary = json.loads((camp / "summary.json").read_text())
    if "/configs/" in summary.get("config", ""):  # a checkout's path: the shipped config's
        summary["config"] = "configs/" + summary["config"].rsplit("/configs/", 1)[1]
    seed_runs = [camp / f"seed_{e['seed_index']}" for e in summary["per_seed"]]
    ranks = [_best_validation(r) for r in seed_runs]
    pick = max(range(len(ranks)), key=lambda k: ranks[k])
    extra = {"selected_at_steps": [_selected_at(r) for r in seed_runs],
             "validation_score": [v for _, v in ranks],
             "beats_reference": [q for q, _ in ranks],
             "shipped": None if shipped is None else {
                 "folder": f"agents/policies/{shipped}",
                 "seed_index": summary["per_seed"][pick]["seed_index"],
                 "training_seed": summary["training_seeds"][pick],
                 "why": "the best validation score (selection_score of eval/best) of the "
                        "campaign's seeds, a seed whose policy beats the selection's reference "
                        "on every validation task first (select_reference); the test seeds "
                        "played no part"}}
    return label, summary, extra


def _reference_drift(committed: dict, ref: dict) -> dict:
    """How far the reference runs' servo errors moved since the committed results (whose rows
    were divided by the references of their time): per reference and hold, the committed
    per-test-seed values and the relative change of their mean."""
    out = {}
    for r in ("pi_kp1", "lqg", "mpc"):
        if r not in committed["rows"] or r not in ref["three_sigma_mdeg"]:
            continue
        out[r] = {}
        for h in HOLDS:
            old = np.asarray(committed["rows"][r]["holds"][h]["per_test_seed"], float)
            new = np.asarray(ref["three_sigma_mdeg"][r][h], float)
            out[r][h] = {"committed_per_test_seed": old.tolist(),
                         "relative_change_of_mean": float(new.mean() / old.mean() - 1.0)}
    return out


def build(runs: Path, out: Path, refs: Path, figures: Path, keep_from: Path = RESULTS,
          scenario_refs: Path = SCENARIO_REFERENCES) -> None:
    """The results file from the campaigns' summaries and the reference runs; the curves.

    The tracking, step and slew columns: the agents whose campaigns scored those scenarios
    (``test_scenarios``), the references of ``scenario_refs`` (when the file exists).

    An agent whose campaign is not under ``runs`` keeps its row of the committed results file
    (``keep_from``) as it is, marked ``kept_from``: the trained runs are not in the repository,
    and a row is only ever computed from its campaign's own summary.
    """
    ref = json.loads(refs.read_text())
    committed = json.loads(keep_from.read_text()) if keep_from.is_file() else None
    agents, kept = {}, {}
    figures.mkdir(parents=True, exist_ok=True)
    for key, (label, folder, shipped) in AGENTS.items():
        camp = runs / folder
        if (camp / "summary.json").is_file():
            agents[key] = _campaign(key, camp, label, shipped)
            for png in sorted(camp.glob("curves_*.png")):
                shutil.copyfile(png, figures / f"{key}_{png.name}")
        elif committed is not None and key in committed["rows"]:
            kept[key] = {**committed["rows"][key], "kept_from": committed["rows"][key].get(
                "kept_from", committed["meta"].get("date_utc", "the committed results"))}
            print(f"{key}: no {camp / 'summary.json'}; its committed row is kept (no pointing scores)")
        else:
            print(f"skipping {key}: no {camp / 'summary.json'}")
    meta = {"date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "references": str(refs.relative_to(ROOT)) if refs.is_relative_to(ROOT) else str(refs),
            "yardstick_analytic_three_sigma_mdeg": ref.get("yardstick_analytic_three_sigma_mdeg"),
            "protocol": "training seeds 10000 + 1000 k (k = 0-4), validation seeds 1000-1005 "
                        "(2000-step holds, select_by three_sigma, or pointing for the agents "
                        "trained on the pointing error; the general agents: every bench scenario, "
                        "select_by general), test seeds 0-9 (3000-step holds, 5-s "
                        "warm-up); the validation-selected policy (eval/best) is scored",
            "kept_rows": {k: "its campaign's runs are not in the repository: the row is the "
                             "committed one (servo error only, its ratios against the references "
                             "of its time)" for k in kept},
            "yardstick_simulated_three_sigma_mdeg": ref["three_sigma_mdeg"].get("yardstick"),
            "yardstick_note": "the yardstick simulated (references file) is not tabled: its design "
                              "ignores the 0.2 deg/s^2 acceleration limit, and on front-hold test "
                              "seeds 1 and 3 it saturates (548 and 2342 of 3000 steps at the "
                              "limit; 1.47 and 245 mdeg); the table gives its analytic value"}
    if kept:
        meta["kept_rows_reference_drift"] = committed["meta"].get("kept_rows_reference_drift") \
            or _reference_drift(committed, ref)
    references_ = {k: _reference(ref, k) for k in TABLE_REFERENCES}
    with_pointing = {k for k, (_, s, _) in agents.items() if has_pointing(s)}
    for key, (label, folder, campaign) in SINGLE_POLICIES.items():
        if campaign is None or campaign not in with_pointing:
            references_[key] = (label, *_score_shipped(folder, ref["test_seeds"]))
    for key in POINTING_CONTROLLERS:
        if key in ref["labels"]:
            references_[key] = _reference(ref, key)
    analytic = {"yardstick_analytic": ("yardstick, expected value (H2 analysis)",
                                       ref["yardstick_analytic_three_sigma_mdeg"],
                                       ref.get("yardstick_analytic_pointing_three_sigma_mdeg"))}
    if ref.get("pointing_yardstick_analytic"):
        py = ref["pointing_yardstick_analytic"]
        analytic["pointing_yardstick_analytic"] = (
            "pointing yardstick, expected value (H2 analysis of the pointing cost)",
            py["three_sigma_mdeg"], py["pointing_three_sigma_mdeg"])
    scen_refs = None
    if scenario_refs.is_file():
        sref = json.loads(scenario_refs.read_text())
        if sref["test_seeds"] != ref["test_seeds"]:
            raise ValueError(f"{scenario_refs}: test seeds {sref['test_seeds']} differ from "
                             f"{refs}'s {ref['test_seeds']}")
        scen_refs = sref["figures"]
        meta["scenario_references"] = (str(scenario_refs.relative_to(ROOT))
                                       if scenario_refs.is_relative_to(ROOT) else str(scenario_refs))
    results = build_results(agents, references_, ref["test_seeds"], meta, analytic, scen_refs)
    rows = results["rows"]
    results["rows"] = {**{k: v for k, v in rows.items() if v["kind"] != "agent"},
                       **{k: kept[k] if k in kept else rows[k] for k in AGENTS if k in kept or k in rows}}
    out.write_text(json.dumps(results, indent=1) + "\n")
    print(f"wrote {out} ({len(agents)} agents from campaigns, {len(kept)} kept)")


def _reference(ref: dict, key: str) -> tuple:
    """A reference controller's ``(label, servo, pointing)`` from the references file."""
    pointing = ref.get("pointing_three_sigma_mdeg", {}).get(key)
    return ref["labels"][key], ref["three_sigma_mdeg"][key], pointing


def _score_shipped(folder: str, test_seeds: list[int]) -> tuple[dict, dict]:
    """A shipped policy's 3σ servo and pointing errors per test seed in both holds, scored as
    the campaigns score (the seeds at once through the batched controller)."""
    from dss14_env.agents.evaluation import DSS14_TASKS, FINAL_SCORING, run_task
    from dss14_env.agents.policy import load_policy, shipped_policy

    ctrl = load_policy(shipped_policy(folder))
    res = {t.name: run_task(ctrl, t, test_seeds, 3000, access=FINAL_SCORING)
           for t in DSS14_TASKS}
    return ({h: r["three_sigma_mdeg"].tolist() for h, r in res.items()},
            {h: r["pointing_three_sigma_mdeg"].tolist() for h, r in res.items()})


def ship(runs: Path, results_path: Path) -> None:
    """Copy each shipped agent's chosen seed (the results file's ``shipped``: the best
    validation score) into ``agents/policies/<name>/``: its ``eval/best`` policy folder, the
    run's validation history and training summary."""
    results = json.loads(results_path.read_text())
    for key, row in results["rows"].items():
        shipped = row.get("shipped")
        if not shipped or row.get("kept_from"):  # a kept row: its runs are not here
            continue
        run = runs / AGENTS[key][1] / f"seed_{shipped['seed_index']}"
        dest = ROOT / shipped["folder"]
        ship_run(run, dest)
        print(f"{key}: {run} -> {dest.relative_to(ROOT)}")


def campaign_block(path: Path) -> str:
    """The learned policies' robustness campaign for docs/results/rl_results.md: what ran, then the campaign's
    own table (:func:`dss14_env.bench.campaign_report.main_table`)."""
    from dss14_env.bench.campaign_report import main_table
    from dss14_env.bench.plan import control_period

    if not path.is_file():
        return (f"(no `{path.name}` yet: `dss14 campaign --ray --out campaign_out`, then keep its "
                f"results.json)")
    res = json.loads(path.read_text())
    c = res["campaign"]
    s = c["spec"]
    return "\n".join([
        f"`dss14 campaign --plants {s['plants']} --controllers {' '.join(s['controllers'])} "
        f"--ray` (`{path.relative_to(ROOT).as_posix()}`): {s['plants']} plants drawn from the "
        f"report's hydraulic ranges (stable part), one {s['steps'] * control_period():g}-s hold per "
        f"plant and condition, every controller on the same plants and gusts; medians, 95th percentiles and "
        f"worst cases with 95 % bootstrap intervals over plants, requirement shares with Wilson "
        f"intervals (docs/scale.md explains the table). Wall time {c['wall_time_s']['total']:.0f} s.",
        "", main_table(res), ""])


def _cpu_per_seed(cpu_log: Path, n: int) -> list[float | None]:
    """CPU seconds of each seed (training and its test scoring) from a log of lines
    ``epoch_s cpu_s seeds_done`` sampled from the campaign's process (its CPU time as each
    seed ended, to the sampling period)."""
    rows = [line.split() for line in cpu_log.read_text().splitlines() if len(line.split()) == 3]
    at_done: dict[int, float] = {}
    for _, cpu, done in rows:
        at_done.setdefault(int(done), float(cpu))  # the first sample after the count rose
    ends = [at_done.get(k) for k in range(1, n + 1)]
    starts = [0.0] + ends[:-1]
    return [None if e is None or s is None else e - s for s, e in zip(starts, ends, strict=True)]


def recipe(campaign: Path, out: Path, cpu_log: Path | None) -> None:
    """The general recipe's report from its campaign (module doc): the pointing-aware LQGs (fixed
    and scheduled on the wind reading) scored on the campaign's test episodes beside its PI and
    LQG, each seed's validation score, the report
    (:func:`dss14_env.agents.recipe_report.recipe_report`) and its profile figure."""
    from dss14_env.agents.campaign import selected_evaluation
    from dss14_env.agents.campaign_report import task_scores
    from dss14_env.agents.evaluation import FINAL_SCORING, dss14_tasks, task_env
    from dss14_env.agents.recipe_report import recipe_report
    from dss14_env.baselines.lqg import PointingLQGController
    from dss14_env.baselines.scheduled import ScheduledPointingLQGController

    summary = json.loads((campaign / "summary.json").read_text())
    proto = summary["protocol"]
    extra: dict = {"lqg_pointing": {}, "lqg_pointing_sched": {}}
    for t in dss14_tasks(scenarios=[t["name"] for t in proto["tasks"]]):
        for name, cls in (("lqg_pointing", PointingLQGController),
                          ("lqg_pointing_sched", ScheduledPointingLQGController)):
            env = task_env(t)
            try:
                extra[name].update(task_scores(cls(env), [t], proto["test_seeds"], proto["test_steps"],
                                               FINAL_SCORING))
            finally:
                env.close()
    validation = {}
    for e in summary["per_seed"]:
        sel = selected_evaluation(campaign / e["run"] / "eval" / "evaluations.npz")
        validation[e["seed_index"]] = None if sel is None else float(sel[1][1])
    report = recipe_report(summary, extra, validation)
    if cpu_log is not None:
        for r, cpu in zip(report["per_seed"], _cpu_per_seed(cpu_log, len(report["per_seed"])), strict=True):
            r["cpu_s_train_and_score"] = cpu
    cfg_src = summary["config"]
    doc = {"what": "the general recipe on >= 10 training seeds: each seed's validation-selected policy "
                   "(eval/best) scored once on the sealed test seeds beside the PI, the LQG and the "
                   "pointing-aware LQGs (fixed, scheduled on the wind reading) on the same episodes "
                   "(dss14_env.agents.recipe_report)",
           "config": "configs/" + Path(cfg_src).name if "/configs/" in cfg_src else cfg_src,
           "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"), "machine": _machine(),
           "protocol": proto, **report}
    if out.is_file():  # a grid or shipped entry of an earlier run of the other commands stays
        old = json.loads(out.read_text())
        doc.update({k: old[k] for k in ("grid", "shipped") if k in old})
    _write_report(doc, out)
    _profile_figure(doc, FIGURES / f"{out.stem.removeprefix('rl_')}_profile.png")


def _write_report(doc: dict, path: Path) -> None:
    """A recipe report and, for a report with the moves' settled figures, its tables beside it
    (``<name>.md``, :func:`dss14_env.agents.recipe_report.recipe_markdown`)."""
    from dss14_env.agents.recipe_report import recipe_markdown

    path.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {path}")
    if "success_rate_headline" in doc:
        md = path.with_suffix(".md")
        md.write_text(f"# {doc['config']}: the general recipe on {len(doc['per_seed'])} training seeds\n\n"
                      f"Generated from `{path.name}` by `scripts/rl_results.py` (never typed).\n\n"
                      + recipe_markdown(doc))
        print(f"wrote {md}")


def _profile_figure(doc: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    prof = doc["profile"]
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    ax.step(prof["tau"], prof["worst_scenario"], where="post", label="worst scenario per seed")
    ax.step(prof["tau"], prof["all_scenarios"], where="post", label="every (seed, scenario)")
    ax.axvline(1.0, color="grey", lw=0.8, ls="--")
    ax.set_xlabel("tau: pointing error / PI's")
    ax.set_ylabel("fraction with ratio <= tau")
    ax.set_title(f"{doc['config']}: {len(doc['per_seed'])} training seeds")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


def shipping_report() -> Path | None:
    """The recipe report whose policy ``agents/policies/<RECIPE_SHIPPED>/`` holds (the one with a
    ``shipped`` entry), or None.

    :raises ValueError: more than one report claims the folder
    """
    found = [p for p in RECIPE_REPORTS.values() if p.is_file() and "shipped" in json.loads(p.read_text())]
    if len(found) > 1:
        raise ValueError(f"recipe reports {', '.join(p.name for p in found)} each claim the shipped folder")
    return found[0] if found else None


def ship_recipe(campaign: Path, report_path: Path) -> None:
    """Copy the recipe's best-validation seed (the report's ``shipped_seed_index``: chosen on the
    validation seeds, never the test seeds) into ``agents/policies/<RECIPE_SHIPPED>/`` and record
    its per-test-seed hold figures in the report (the shipped policy's regression figures); a
    report whose policy the folder held before keeps that entry as ``shipped_before``."""
    doc = json.loads(report_path.read_text())
    k = doc["shipped_seed_index"]
    summary = json.loads((campaign / "summary.json").read_text())
    entry = next(e for e in summary["per_seed"] if e["seed_index"] == k)
    run = campaign / entry["run"]
    dest = ROOT / "agents" / "policies" / RECIPE_SHIPPED
    ship_run(run, dest)
    doc["shipped"] = {"folder": f"agents/policies/{RECIPE_SHIPPED}", "seed_index": k,
                      "training_seed": entry["training_seed"],
                      "why": "the best validation score of the campaign's seeds",
                      "holds": {h: {"per_test_seed": entry["best"][h]["three_sigma_mdeg"],
                                    "pointing": {"per_test_seed":
                                                 entry["best"][h]["pointing_three_sigma_mdeg"]}}
                                for h in HOLDS}}
    report_path.write_text(json.dumps(doc, indent=1) + "\n")
    for other in RECIPE_REPORTS.values():
        if other.resolve() != report_path.resolve() and other.is_file():
            old = json.loads(other.read_text())
            if "shipped" in old:
                old["shipped_before"] = {**old.pop("shipped"), "replaced_by": report_path.name}
                other.write_text(json.dumps(old, indent=1) + "\n")
    print(f"seed index {k}: {run} -> {dest.relative_to(ROOT)}")


def grid(report_path: Path, campaign: Path | None = None) -> None:
    """The general policy, the PI and the pointing-aware LQGs (fixed and scheduled) in holds over
    :data:`RECIPE_GRID` (the test seeds, :data:`RECIPE_GRID_STEPS` steps): the worse axis's 3σ
    pointing error per episode, and the policy's ratio to each with a paired bootstrap interval
    over the test seeds (:func:`dss14_env.core.stats.ratio_ci`); into the report's ``grid``.
    The policy is the shipped one, or with ``campaign`` the report's best-validation seed's
    (``shipped_seed_index``, its ``eval/best``) of that campaign."""
    import math

    from dss14_env.agents.evaluation import FINAL_SCORING, dss14_tasks, run_task, task_env
    from dss14_env.agents.policy import load_policy, shipped_policy
    from dss14_env.agents.recipe_report import BOOTSTRAP_SEED
    from dss14_env.baselines.lqg import PointingLQGController
    from dss14_env.baselines.pi import PIController
    from dss14_env.baselines.scheduled import ScheduledPointingLQGController
    from dss14_env.core.stats import ratio_ci

    if campaign is None:
        folder = shipped_policy(RECIPE_SHIPPED)
        label = f"agents/policies/{RECIPE_SHIPPED}"
    else:
        k = json.loads(report_path.read_text())["shipped_seed_index"]
        summary = json.loads((campaign / "summary.json").read_text())
        entry = next(e for e in summary["per_seed"] if e["seed_index"] == k)
        folder = campaign / entry["run"] / "eval" / "best"
        label = f"the best-validation seed's policy (training seed {entry['training_seed']})"
    makers = {RECIPE_SHIPPED: lambda env: load_policy(folder),
              "pi_kp1": lambda env: PIController(env, "kp1"), "lqg_pointing": PointingLQGController,
              "lqg_pointing_sched": ScheduledPointingLQGController}
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    conditions = []
    for speed, direction in RECIPE_GRID:
        (task,) = dss14_tasks({"wind_speed_kmh": speed, "wind_direction": math.radians(direction)},
                              scenarios=["hold_front"])
        vals = {}
        for name, make in makers.items():
            env = task_env(task)
            try:
                r = run_task(make(env), task, TEST_SEEDS, RECIPE_GRID_STEPS, access=FINAL_SCORING)
            finally:
                env.close()
            vals[name] = np.maximum(r["pointing_three_sigma_mdeg_el"], r["pointing_three_sigma_mdeg_xel"])
        c = {"wind_speed_kmh": speed, "wind_direction_deg": direction,
             "pointing_mdeg": {k: float(np.mean(v)) for k, v in vals.items()},
             "per_test_seed": {k: v.tolist() for k, v in vals.items()}}
        for ref in ("pi_kp1", "lqg_pointing", "lqg_pointing_sched"):
            est = ratio_ci(vals[RECIPE_SHIPPED], vals[ref], np.mean, rng, paired=True)
            c[f"ratio_{ref}"] = {"value": est.value, "low": est.low, "high": est.high}
        conditions.append(c)
        print(f"{speed:g} km/h {direction:g} deg: " + ", ".join(f"{k} {v:.2f}" for k, v in
                                                               c["pointing_mdeg"].items()), flush=True)
    doc = json.loads(report_path.read_text()) if report_path.is_file() else {}
    doc["grid"] = {"what": f"holds, test seeds {TEST_SEEDS[0]}-{TEST_SEEDS[-1]}, {RECIPE_GRID_STEPS} steps, "
                           "5-s warm-up; the worse axis's 3-sigma pointing error (mdeg), mean over the "
                           "seeds; ratios of means with 95 % paired percentile-bootstrap intervals",
                   "policy": label, "controllers": list(makers), "conditions": conditions}
    _write_report(doc, report_path)


def stale(results_path: Path, out: Path) -> None:
    """Score the results file's shipped policies (those whose folder the recipe did not take)
    again on the test seeds on the shipped drive: their per-test-seed hold figures there (the
    regression checks' figures for the policies marked stale, docs/rl.md)."""
    results = json.loads(results_path.read_text())
    report = shipping_report()
    taken = json.loads(report.read_text())["shipped"]["folder"] if report is not None else None
    rows = {}
    for key, row in results["rows"].items():
        if not row.get("shipped") or row["shipped"]["folder"] == taken:
            continue
        servo, pointing = _score_shipped(Path(row["shipped"]["folder"]).name, TEST_SEEDS)
        rows[key] = {"folder": row["shipped"]["folder"],
                     "holds": {h: {"per_test_seed": servo[h], "pointing": {"per_test_seed": pointing[h]}}
                               for h in HOLDS}}
        print(key, {h: round(float(np.mean(pointing[h])), 2) for h in HOLDS}, flush=True)
    doc = {"what": "the shipped policies trained on the earlier drive, re-scored on the shipped drive: "
                   "3-sigma servo (loaded axis) and pointing (swung axis) errors per test seed, 3000-step "
                   "holds (the regression checks' figures; they are marked stale in docs/rl.md)",
           "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"), "machine": _machine(),
           "test_seeds": TEST_SEEDS, "rows": rows}
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {out}")


def render(results_path: Path, check: bool) -> int:
    """Fill the generated blocks of the documents; with ``check`` only report stale ones."""
    from dss14_env.agents.recipe_report import recipe_markdown
    from dss14_env.reproduce import fill_blocks, find_blocks

    blocks = {**rl_tables(json.loads(results_path.read_text())), "rl-campaign": campaign_block(CAMPAIGN),
              **{name: recipe_markdown(json.loads(path.read_text())) if path.is_file()
                 else f"(no `{path.name}` yet: `python scripts/rl_results.py recipe`)"
                 for name, path in RECIPE_REPORTS.items()}}
    stale = []
    for doc, names in DOCUMENTS.items():
        text = doc.read_text()
        missing = set(names) - set(find_blocks(text))  # other blocks are other scripts' (rl-rescore)
        if missing:
            print(f"{doc}: generated blocks {sorted(missing)} missing", file=sys.stderr)
            return 2
        new = fill_blocks(text, {n: blocks[n] for n in names})
        if new != text:
            stale.append(doc)
            if not check:
                doc.write_text(new)
    for doc in stale:
        print(f"{doc.relative_to(ROOT)}: {'out of date' if check else 'rewritten'}")
    return 1 if (check and stale) else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("references", help="run the reference controllers on the test seeds")
    r.add_argument("--out", type=Path, default=REFERENCES)
    sr = sub.add_parser("scenario-references",
                        help="the PI and LQG in the track, step and slew on the test seeds")
    sr.add_argument("--out", type=Path, default=SCENARIO_REFERENCES)
    b = sub.add_parser("build", help="the results file from the campaigns")
    b.add_argument("--runs", type=Path, default=Path("runs"))
    b.add_argument("--references", type=Path, default=REFERENCES)
    b.add_argument("--out", type=Path, default=RESULTS)
    b.add_argument("--figures", type=Path, default=FIGURES)
    b.add_argument("--keep-from", type=Path, default=RESULTS,
                   help="the results file whose rows are kept for campaigns not under --runs")
    b.add_argument("--scenario-references", type=Path, default=SCENARIO_REFERENCES,
                   help="the references of the tracking, step and slew columns (if the file exists)")
    s = sub.add_parser("ship", help="copy the shipped agents' chosen seeds to agents/policies")
    s.add_argument("--runs", type=Path, default=Path("runs"))
    s.add_argument("--results", type=Path, default=RESULTS)
    rc = sub.add_parser("recipe", help="the general recipe's many-seed report from its campaign")
    rc.add_argument("--campaign", type=Path, default=Path("runs") / "ppo_general_lqg")
    rc.add_argument("--out", type=Path, default=RECIPE)
    rc.add_argument("--cpu-log", type=Path, default=None,
                    help="lines 'epoch_s cpu_s seeds_done' sampled from the campaign's process")
    sh = sub.add_parser("ship-recipe", help="ship the recipe's best-validation seed")
    sh.add_argument("--campaign", type=Path, default=Path("runs") / "ppo_general_lqg")
    sh.add_argument("--report", type=Path, default=RECIPE, help="the campaign's recipe report")
    g = sub.add_parser("grid", help="the shipped general policy on the wind direction/speed grid "
                                    "(into the shipping report)")
    g.add_argument("--report", type=Path, default=None, help="the report (default: the shipping one)")
    g.add_argument("--campaign", type=Path, default=None,
                   help="score the report's best-validation seed of this campaign, not the shipped folder")
    sub.add_parser("stale", help="re-score the stale shipped policies on the shipped drive")
    d = sub.add_parser("render", help="the tables of docs/results/rl_results.md")
    d.add_argument("--results", type=Path, default=RESULTS)
    d.add_argument("--check", action="store_true", help="only check; exit 1 if out of date")
    args = ap.parse_args(argv)
    if args.cmd == "references":
        references(args.out)
    elif args.cmd == "scenario-references":
        scenario_references(args.out)
    elif args.cmd == "build":
        build(args.runs, args.out, args.references, args.figures, args.keep_from,
              args.scenario_references)
    elif args.cmd == "ship":
        ship(args.runs, args.results)
    elif args.cmd == "recipe":
        recipe(args.campaign, args.out, args.cpu_log)
    elif args.cmd == "ship-recipe":
        ship_recipe(args.campaign, args.report)
    elif args.cmd == "grid":
        grid(args.report or shipping_report() or RECIPE, args.campaign)
    elif args.cmd == "stale":
        stale(RESULTS, STALE)
    else:
        return render(args.results, args.check)
    return 0


if __name__ == "__main__":
    sys.exit(main())
