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
DOCUMENTS = {ROOT / "docs" / "results" / "rl_results.md": ("rl-table", "rl-seeds", "rl-campaign")}
#: the robustness campaign of the learned policies beside PI and LQG (``dss14 campaign``,
#: :func:`dss14_env.bench.campaign_report.compact_results` of its results.json), and the command
CAMPAIGN = ROOT / "docs" / "results" / "campaign_policies.json"
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
    "ppo_general": ("general plain PPO: one policy for tracks, holds, steps and slews", "ppo_general",
                    "ppo_general"),
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
        if dest.exists():
            shutil.rmtree(dest)
        dest.mkdir(parents=True)
        for name in ("policy.pt", "normalization.npz", "config.yaml"):
            shutil.copyfile(run / "eval" / "best" / name, dest / name)
        shutil.copyfile(run / "eval" / "evaluations.npz", dest / "evaluations.npz")
        shutil.copyfile(run / "train_summary.json", dest / "train_summary.json")
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


def render(results_path: Path, check: bool) -> int:
    """Fill the generated blocks of the documents; with ``check`` only report stale ones."""
    from dss14_env.reproduce import fill_blocks, find_blocks

    blocks = {**rl_tables(json.loads(results_path.read_text())), "rl-campaign": campaign_block(CAMPAIGN)}
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
    else:
        return render(args.results, args.check)
    return 0


if __name__ == "__main__":
    sys.exit(main())
