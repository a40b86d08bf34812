"""The learned agents' results: reference runs, the committed results file, its tables.

Three steps, each writing what the next reads::

    # 1. the reference controllers on the test seeds (the benchmark's runner; ~5 min on one core)
    python scripts/rl_results.py references            # -> docs/results/rl_references.json
    # 2. the training campaigns (dss14 train <algo> --config <cfg> --seeds 0-4 --out runs/<agent>),
    #    then the results file and the learning-curve figures
    python scripts/rl_results.py build --runs runs  # -> docs/results/rl_results.json, rl/*.png
    # 3. the shipped policies: each shipped agent's seed with the best validation score
    python scripts/rl_results.py ship --runs runs      # -> agents/policies/<name>/
    # 4. the tables of README.md and docs/rl.md (rendered from the results file, never typed)
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

from dss14_env.agents.results import HOLDS, build_results, rl_tables

ROOT = Path(__file__).resolve().parents[1]

RESULTS = ROOT / "docs" / "results" / "rl_results.json"
REFERENCES = ROOT / "docs" / "results" / "rl_references.json"
FIGURES = ROOT / "docs" / "results" / "rl"
#: the generated blocks and the documents that show them
DOCUMENTS = {ROOT / "README.md": ("rl-table",), ROOT / "docs" / "rl.md": ("rl-table", "rl-seeds")}
#: the reference controllers: runner name -> label
REFERENCE_CONTROLLERS = {"pi_kp1": "PI (report: kp 1, ki 0.3)", "lqg": "LQG", "mpc": "MPC",
                         "yardstick": "yardstick (H2-optimal, knows the wind)"}
#: the references in the table: the yardstick's simulated run is kept in the references file
#: but not tabled (it is a bound of the linear model: under the plant's 0.2 deg/s^2
#: acceleration limit, which its design ignores, it saturates on some seeds -- front hold,
#: test seed 3: 2342 of 3000 steps at the limit, 245 mdeg); the table shows its analytic value
TABLE_REFERENCES = ("pi_kp1", "lqg", "mpc")
#: the agents: key -> (label, campaign folder under --runs, shipped policy folder or None)
AGENTS = {
    "ppo_plain": ("plain PPO", "ppo_plain", "ppo_plain"),
    "recurrent_ppo": ("recurrent PPO (LSTM)", "recurrent_ppo", None),
    "ppo_residual_lqg": ("model-informed PPO (residual on the LQG)", "ppo_residual_lqg",
                         "ppo_residual_lqg"),
    "sac": ("SAC", "sac", None),
    "ppo_residual_pi": ("residual PPO on the PI", "ppo_residual_pi", None),
    "ppo_residual_pi_hold": ("residual PPO on the PI, benchmark wind", "ppo_residual_pi_hold", None),
}
#: single policies scored like the campaigns' (one training seed: an interval over test seeds
#: only): key -> (label, shipped folder)
SINGLE_POLICIES = {"residual_pi_shipped": ("residual PPO on the PI, the policy shipped first "
                                           "(one training seed)", "residual_pi")}
TEST_SEEDS = list(range(10))


def _machine() -> dict:
    return {"cpu_count": os.cpu_count(), "load_average": list(os.getloadavg()),
            "python": platform.python_version(), "platform": platform.platform()}


def references(out: Path) -> None:
    """Run the reference controllers on the test seeds of both holds (full 3000-step episodes)."""
    from dss14_env.bench.runner import run

    res = run(list(REFERENCE_CONTROLLERS), list(HOLDS), TEST_SEEDS)
    values: dict[str, dict[str, list[float]]] = {
        c: {h: [float("nan")] * len(TEST_SEEDS) for h in HOLDS} for c in REFERENCE_CONTROLLERS}
    for e in res["episodes"]:
        if e["scenario"] in HOLDS:
            axis = HOLDS[e["scenario"]]
            values[e["controller"]][e["scenario"]][TEST_SEEDS.index(e["seed"])] = \
                e["servo_error_mdeg"][axis]["three_sigma"]
    analytic = {h: res["yardstick"][h]["three_sigma_mdeg"][0 if a == "az" else 1]
                for h, a in HOLDS.items() if h in res.get("yardstick", {})}
    doc = {"what": "3-sigma servo error (mdeg) of the loaded axis per test seed, the benchmark's "
                   "runner (dss14_env.bench.runner.run), hold scenarios, 3000 steps, 5-s warm-up",
           "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "machine": _machine(), "test_seeds": TEST_SEEDS, "wall_time_s": res["meta"]["wall_time_s"],
           "labels": REFERENCE_CONTROLLERS, "three_sigma_mdeg": values,
           "yardstick_analytic_three_sigma_mdeg": analytic}
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {out}")


def _selected_at(run: Path) -> int | None:
    """The step of the validation-selected policy (the best selection score) of a run."""
    path = run / "eval" / "evaluations.npz"
    if not path.is_file():
        return None
    with np.load(path, allow_pickle=False) as d:
        if "selection_score" not in d.files:
            return None
        return int(d["timesteps"][int(np.argmax(d["selection_score"]))])


def _best_validation(run: Path) -> float:
    with np.load(run / "eval" / "evaluations.npz", allow_pickle=False) as d:
        return float(np.max(d["selection_score"]))


def build(runs: Path, out: Path, refs: Path, figures: Path) -> None:
    """The results file from the campaigns' summaries and the reference runs; the curves."""
    ref = json.loads(refs.read_text())
    references_ = {k: (ref["labels"][k], ref["three_sigma_mdeg"][k]) for k in TABLE_REFERENCES}
    agents = {}
    figures.mkdir(parents=True, exist_ok=True)
    for key, (label, folder, shipped) in AGENTS.items():
        camp = runs / folder
        if not (camp / "summary.json").is_file():
            print(f"skipping {key}: no {camp / 'summary.json'}")
            continue
        summary = json.loads((camp / "summary.json").read_text())
        if "/configs/" in summary.get("config", ""):  # a checkout's path: the shipped config's
            summary["config"] = "configs/" + summary["config"].rsplit("/configs/", 1)[1]
        seed_runs = [camp / f"seed_{e['seed_index']}" for e in summary["per_seed"]]
        val = [_best_validation(r) for r in seed_runs]
        pick = int(np.argmax(val))
        extra = {"selected_at_steps": [_selected_at(r) for r in seed_runs],
                 "validation_score": val,
                 "shipped": None if shipped is None else {
                     "folder": f"agents/policies/{shipped}",
                     "seed_index": summary["per_seed"][pick]["seed_index"],
                     "training_seed": summary["training_seeds"][pick],
                     "why": "the best validation score (selection_score of eval/best) of the "
                            "campaign's seeds; the test seeds played no part"}}
        agents[key] = (label, summary, extra)
        for png in sorted(camp.glob("curves_*.png")):
            shutil.copyfile(png, figures / f"{key}_{png.name}")
    meta = {"date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "references": str(refs.relative_to(ROOT)) if refs.is_relative_to(ROOT) else str(refs),
            "yardstick_analytic_three_sigma_mdeg": ref.get("yardstick_analytic_three_sigma_mdeg"),
            "protocol": "training seeds 10000 + 1000 k (k = 0-4), validation seeds 1000-1005 "
                        "(2000-step holds, select_by three_sigma), test seeds 0-9 (3000-step "
                        "holds, 5-s warm-up); the validation-selected policy (eval/best) is scored",
            "yardstick_simulated_three_sigma_mdeg": ref["three_sigma_mdeg"].get("yardstick"),
            "yardstick_note": "the yardstick simulated (references file) is not tabled: its design "
                              "ignores the 0.2 deg/s^2 acceleration limit, and on front-hold test "
                              "seeds 1 and 3 it saturates (548 and 2342 of 3000 steps at the "
                              "limit; 1.47 and 245 mdeg); the table gives its analytic value"}
    from dss14_env.agents.evaluation import DSS14_TASKS, run_task
    from dss14_env.agents.policy import load_policy, shipped_policy

    for key, (label, folder) in SINGLE_POLICIES.items():
        ctrl = load_policy(shipped_policy(folder))  # scored as the campaigns score (10 seeds at once)
        values = {t.name: run_task(ctrl, t, ref["test_seeds"], 3000)["three_sigma_mdeg"].tolist()
                  for t in DSS14_TASKS}
        references_[key] = (label, values)
    analytic = {"yardstick_analytic": ("yardstick, expected value (H2 analysis)",
                                       ref["yardstick_analytic_three_sigma_mdeg"])}
    results = build_results(agents, references_, ref["test_seeds"], meta, analytic)
    out.write_text(json.dumps(results, indent=1) + "\n")
    print(f"wrote {out} ({len(agents)} agents)")


def ship(runs: Path, results_path: Path) -> None:
    """Copy each shipped agent's chosen seed (the results file's ``shipped``: the best
    validation score) into ``agents/policies/<name>/``: its ``eval/best`` policy folder, the
    run's validation history and training summary."""
    results = json.loads(results_path.read_text())
    for key, row in results["rows"].items():
        shipped = row.get("shipped")
        if not shipped:
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


def render(results_path: Path, check: bool) -> int:
    """Fill the generated blocks of the documents; with ``check`` only report stale ones."""
    from dss14_env.reproduce import fill_blocks, find_blocks

    blocks = rl_tables(json.loads(results_path.read_text()))
    stale = []
    for doc, names in DOCUMENTS.items():
        text = doc.read_text()
        found = {n for n in find_blocks(text) if n.startswith("rl-")}
        if found != set(names):
            print(f"{doc}: generated blocks {sorted(found)}, expected {sorted(names)}", file=sys.stderr)
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
    b = sub.add_parser("build", help="the results file from the campaigns")
    b.add_argument("--runs", type=Path, default=Path("runs"))
    b.add_argument("--references", type=Path, default=REFERENCES)
    b.add_argument("--out", type=Path, default=RESULTS)
    b.add_argument("--figures", type=Path, default=FIGURES)
    s = sub.add_parser("ship", help="copy the shipped agents' chosen seeds to agents/policies")
    s.add_argument("--runs", type=Path, default=Path("runs"))
    s.add_argument("--results", type=Path, default=RESULTS)
    d = sub.add_parser("render", help="the tables of README.md and docs/rl.md")
    d.add_argument("--results", type=Path, default=RESULTS)
    d.add_argument("--check", action="store_true", help="only check; exit 1 if out of date")
    args = ap.parse_args(argv)
    if args.cmd == "references":
        references(args.out)
    elif args.cmd == "build":
        build(args.runs, args.out, args.references, args.figures)
    elif args.cmd == "ship":
        ship(args.runs, args.results)
    else:
        return render(args.results, args.check)
    return 0


if __name__ == "__main__":
    sys.exit(main())
