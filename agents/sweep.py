"""Hyperparameter sweeps: one many-seed campaign per point of a grid, ranked with intervals.

A training configuration with a ``sweep`` key (:mod:`dss14_env.agents.config`) names a grid
of points; :func:`train_sweep` trains every point with the same seed indices, as the campaign
of :mod:`dss14_env.agents.campaign` does for one configuration, and writes::

    config.yaml          the sweep's configuration (the shared keys and the sweep)
    <label>/             one campaign per point: seed_<k>/, summary.json, curves_*.png and the
                         point's config.yaml (label: learning_rate=0.0001,log_std_init=-2.5,
                         or point_NN when readable labels are too long)
    sweep.json           per point its values and its summary.json's statistics (per task:
                         the IQM over training seeds with its 95 % bootstrap interval, the
                         per-seed values); the points ranked by IQM per task
    sweep.md             the same as a table

Every (point, seed) pair is one work item of the executor (:mod:`dss14_env.core.parallel`):
in-process one after another, or all of them as Ray tasks, one CPU and one BLAS/torch thread
each, so the same seeds give the same numbers either way.  Seed index ``k`` trains with seed
``config.seed + 1000 k`` at every point: the points differ only in their swept values.

The ranking orders the points by the IQM of each task's metric (lowest 3σ or highest return
first).  Points whose 95 % intervals overlap are not significantly different: with few seeds
the order of such points is not a result.  An interrupted sweep continues with
``resume=True``: every point keeps its finished runs.
"""

from __future__ import annotations

import glob
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from dss14_env.agents.campaign import (
    COMMAND,
    SEED_STRIDE,
    campaign_tasks,
    check_folder_first,
    check_saved_config,
    check_training_seeds,
    open_campaign,
    owned_files,
    run_seed_items,
    say_plan,
    seed_items,
    training_seed,
    write_summary,
)
from dss14_env.agents.config import SweepPoint, TrainConfig, as_config
from dss14_env.agents.envs import check_env
from dss14_env.agents.evaluation import RESEARCH_SEEDS, TEST_STEPS, check_unsealed
from dss14_env.core.outdir import (
    atomic_write_text,
    manifest_kept,
    prepare_output_dir,
    remove_run_files,
    reopen_output_dir,
)
from dss14_env.core.parallel import Executor, SerialExecutor, pinned_threads

#: keys whose change makes another environment (a point with other values is made once before
#: any training, so that a bad one fails first)
ENV_KEYS = ("env_id", "env_kwargs", "env_module", "frame_stack", "eval_env_kwargs")
#: how sweep.json explains its ranking
RANKING_NOTE = ("points sorted by the IQM over training seeds of each task's metric (lowest 3σ or "
                "highest return first); points whose 95 % intervals overlap are not significantly "
                "different; overlaps_first: the point's interval overlaps the first point's (null "
                "with fewer than 2 training seeds: no interval)")


def _point_folders(points: Sequence[SweepPoint]) -> tuple[str, ...]:
    """The folders of the sweep's points (glob patterns of their labels)."""
    return tuple(glob.escape(p.label) for p in points)


def _check_envs(points: Sequence[SweepPoint], sweep: Mapping[str, Any]) -> None:
    """Make the environment of every point whose environment keys differ (before any work)."""
    if not any(key.split(".")[0] in ENV_KEYS for key in sweep):
        return
    seen = set()
    for p in points:
        key = json.dumps({k: getattr(p.config, k) for k in ENV_KEYS}, sort_keys=True)
        if key not in seen:
            seen.add(key)
            with pinned_threads(1):  # as the work items build their models
                check_env(p.config)


def _open(cfg: TrainConfig, points: Sequence[SweepPoint], out: str | Path, seeds: Sequence[int],
          overwrite: bool, resume: bool) -> tuple[Path, list[tuple[Path, set[int]]]]:
    """The sweep folder and, per point, its campaign folder and finished seed indices."""
    if resume:
        folder = Path(out)
        check_saved_config(cfg, folder)
        reopen_output_dir(folder, owned_files(folder), "--out", command=COMMAND)
        remove_run_files(folder, ("sweep.json", "sweep.md"))
    else:
        mine = _point_folders(points)  # this sweep's points, and any before
        folder = prepare_output_dir(out, owned_files(out) + mine, overwrite, "--out", command=COMMAND)
        atomic_write_text(folder / "config.yaml", f"# sweep (from {cfg.source}): one campaign per "
                          f"point of the grid in <label>/; run k of every point trains with seed "
                          f"{cfg.seed} + {SEED_STRIDE} k\n"
                          + yaml.safe_dump(cfg.to_dict(), sort_keys=False))
    campaigns = []
    for p in points:
        sub = folder / p.label
        again = resume and (sub / "config.yaml").is_file()
        campaigns.append(open_campaign(p.config, sub, seeds, overwrite=not again, resume=again))
    return folder, campaigns


def rank_points(points: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The ranking of ``sweep.json``: per policy (``final``, ``best``) and task, the points in
    order of their IQM (lowest 3σ or highest return first), each with its interval and whether
    that overlaps the first point's.

    :param points: ``label`` and ``aggregate`` (a campaign summary's) of every point
    """
    out: dict[str, Any] = {}
    for which in ("final", "best"):
        tasks: dict[str, Any] = {}
        for p in points:
            for task, a in p["aggregate"].get(which, {}).items():
                tasks.setdefault(task, {"metric": a["metric"], "rows": []})["rows"].append((p["label"], a))
        ranked = {}
        for task, t in tasks.items():
            lower = t["metric"] == "mean_three_sigma_mdeg"
            rows = sorted(t["rows"], key=lambda r: r[1]["iqm"]["value"] * (1 if lower else -1))
            first_lo, first_hi = rows[0][1]["iqm"]["ci95"]
            order = []
            for rank, (label, a) in enumerate(rows, 1):
                lo, hi = a["iqm"]["ci95"]
                with_ci = a["iqm"]["n"] >= 2 and rows[0][1]["iqm"]["n"] >= 2 and all(
                    math.isfinite(x) for x in (lo, hi, first_lo, first_hi))
                order.append({"rank": rank, "label": label, "iqm": a["iqm"]["value"], "ci95": [lo, hi],
                              "overlaps_first": (lo <= first_hi and first_lo <= hi) if with_ci else None})
            ranked[task] = {"metric": t["metric"], "better": "lower" if lower else "higher",
                            "order": order}
        if ranked:
            out[which] = ranked
    return out


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def sweep_markdown(report: Mapping[str, Any]) -> str:
    """``sweep.md``: per policy one table, a row per point (its values; per task the IQM with
    its 95 % interval and the point's rank), and how to read the ranking.
    """
    keys = list(report["sweep"])
    lines = [f"# Sweep of {report['config']}", "",
             f"{len(report['points'])} points × {len(report['seed_indices'])} training seeds "
             f"(indices {report['seed_indices']}).  Per task: the IQM over training seeds of the "
             f"metric with its 95 % bootstrap interval, and the point's rank (lowest 3σ or highest "
             f"return first); \"overlaps #1\": the point's interval overlaps the first-ranked "
             f"point's, so the two are not significantly different."]
    for which, tasks in report["ranking"].items():
        ranks = {task: {r["label"]: r for r in t["order"]} for task, t in tasks.items()}
        head = ["point"] + keys + [f"{task}: {t['metric']}" for task, t in tasks.items()]
        lines += ["", f"## {which} policy", "", "| " + " | ".join(head) + " |",
                  "|" + "---|" * len(head)]
        for p in report["points"]:
            cells = [f"`{p['label']}`"] + [json.dumps(p["values"][k]) for k in keys]
            for task in tasks:
                r = ranks[task].get(p["label"])
                if r is None:
                    cells.append("–")
                    continue
                tie = ", overlaps #1" if r["rank"] > 1 and r["overlaps_first"] else ""
                cells.append(f"{_fmt(r['iqm'])} [{_fmt(r['ci95'][0])}, {_fmt(r['ci95'][1])}] "
                             f"(#{r['rank']}{tie})")
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def train_sweep(config: TrainConfig | Mapping[str, Any] | str | Path, seeds: Sequence[int],
                out: str | Path, overwrite: bool = False, test_seeds: Sequence[int] = RESEARCH_SEEDS,
                test_steps: int = TEST_STEPS, figures: bool = True,
                executor: Executor | None = None, resume: bool = False,
                progress: bool | None = None) -> Path:
    """Train every point of a sweep with the same seed indices and rank the points (see the
    module doc).

    :param config: a configuration with a ``sweep`` (a YAML path, a shipped name, a mapping)
    :param seeds: seed indices ``k`` (every point trains all of them)
    :param out: the sweep folder (checked before any work; ``overwrite`` replaces an earlier
        sweep's or campaign's files)
    :param test_seeds: the seeds the points are scored and ranked on, default
        :data:`~dss14_env.agents.evaluation.RESEARCH_SEEDS` (validation seeds 2000-2009): a
        sweep is recipe research and never reads the sealed test seeds
    :param test_steps: episode length of the test episodes, default 3000 (60 s)
    :param figures: draw every point's learning curves
    :param executor: where the (point, seed) items run (:mod:`dss14_env.core.parallel`),
        default one after another in this process
    :param resume: continue the interrupted sweep in ``out`` (same configuration): finished
        runs are scored, not retrained, the others continue from their last checkpoint
    :param progress: each run's steps on stderr (None: the configuration's ``progress_bar``);
        a line as each run starts and ends (with the sweep's ETA) either way
    :return: the sweep folder
    :raises ValueError: no sweep in the configuration, an environment a point cannot make, an
        unusable folder (all before any training)
    :raises SealedSeedError: a sealed test seed in ``test_seeds`` (before any training)
    """
    check_unsealed(test_seeds, None, "sweep: test_seeds")
    cfg = as_config(config)
    if not cfg.sweep:
        raise ValueError(f"{cfg.source}: field 'sweep': is missing (a configuration without a "
                         f"sweep trains with dss14_env.agents.campaign.train_seeds)")
    seeds = [int(k) for k in seeds]
    points = cfg.points()
    for p in points:
        check_training_seeds(p.config, seeds)
    for p in points:  # an environment the tasks cannot be made of: before any work
        campaign_tasks(p.config)
    check_folder_first(cfg, out, overwrite, resume, owned_files(out) + _point_folders(points))
    say_plan(cfg, out, len(points) * len(seeds), resume)
    _check_envs(points, cfg.sweep)
    folder, campaigns = _open(cfg, points, out, seeds, overwrite, resume)
    with manifest_kept(folder):
        return _run_sweep(cfg, points, folder, campaigns, seeds, test_seeds, test_steps, figures,
                          executor, progress)


def _run_sweep(cfg: TrainConfig, points: Sequence[SweepPoint], folder: Path,
               campaigns: list[tuple[Path, set[int]]], seeds: list[int], test_seeds: Sequence[int],
               test_steps: int, figures: bool, executor: Executor | None,
               progress: bool | None = None) -> Path:
    """Train and score every point's seeds in the opened sweep folder (:func:`train_sweep`)."""
    items, labels = [], []
    for p, (sub, finished) in zip(points, campaigns, strict=True):
        items += seed_items(p.config, sub, seeds, finished, test_seeds, test_steps, progress)
        labels += [f"{p.label}/seed_{k}" for k in seeds]
    ex = executor if executor is not None else SerialExecutor()
    done = run_seed_items(ex, items, labels)
    rows = []
    for j, (p, (sub, _)) in enumerate(zip(points, campaigns, strict=True)):
        per_seed = [done[j * len(seeds) + i] for i in range(len(seeds))]
        summary = write_summary(p.config, sub, seeds, per_seed, test_seeds, test_steps, figures)
        rows.append({"label": p.label, "folder": p.label, "values": p.values,
                     "aggregate": summary["aggregate"]})
    report = {"algo": cfg.algo, "env_id": cfg.env_id, "config": cfg.source, "sweep": cfg.sweep,
              "seed_indices": seeds, "training_seeds": [training_seed(cfg, k) for k in seeds],
              "protocol": {"test_seeds": [int(s) for s in test_seeds], "test_steps": int(test_steps),
                           "interval": "95 % percentile bootstrap over training seeds of the IQM "
                                       "(dss14_env.core.stats.iqm_ci), from each point's summary.json",
                           "ranking": RANKING_NOTE},
              "points": rows, "ranking": rank_points(rows)}
    atomic_write_text(folder / "sweep.json", json.dumps(report, indent=2) + "\n")
    atomic_write_text(folder / "sweep.md", sweep_markdown(report))
    return folder


__all__ = ["ENV_KEYS", "RANKING_NOTE", "rank_points", "sweep_markdown", "train_sweep"]
