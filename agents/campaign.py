"""Many training seeds, one folder, honest statistics.

:func:`train_seeds` trains one run per seed index ``k`` (one after another in this process, or
as Ray tasks through an executor of :mod:`dss14_env.core.parallel`) into
``<out>/seed_<k>/`` with the training seed ``config.seed + 1000 k`` (so the sub-environments
of different runs never share a seed), then scores every run's final and best
(``eval/best``) policy, loaded back from disk, on the test seeds (never seen in training,
:mod:`dss14_env.agents.evaluation`), and writes::

    summary.json        per training seed: training wall time and environment steps, the 3σ
                        servo and pointing errors (DSS14) or return of every test episode and
                        their mean per task, and (DSS14) every test episode's figures of the
                        bench; over the training seeds: the interquartile mean with its 95 %
                        bootstrap interval (dss14_env.core.stats.iqm_ci), the mean, min and
                        max; the references (PI, LQG) on the same test and validation episodes
    summary.md          the test figures per training seed, their IQM and the references
                        (dss14_env.agents.campaign_report; ``dss14 train --train-seeds`` prints it)
    curves_<task>.png   validation 3σ (servo and pointing) and return vs environment steps: IQM
                        over training seeds with its 95 % bootstrap band, every seed's curve
                        and the references' validation 3σ as lines
    config.yaml         the configuration the runs share (seed: the base seed)

The test tasks are the DSS14 scenarios of the configuration's ``test_scenarios`` (default the
two holds; any of :data:`dss14_env.agents.evaluation.SCENARIO_TASKS`: holds, track, step, slew),
each scored with the bench's figures on the bench's episodes.

An interrupted campaign continues with ``resume=True`` (``dss14 train ... --train-seeds ...
--resume``): the seeds whose run finished with the campaign's configuration are scored
again, not retrained; the others continue from their last checkpoint (Ctrl-C and SIGTERM save
one where they stop, :func:`dss14_env.agents.train.train`), or train anew without one.

The interval resamples training seeds (the independent units); with fewer than 5 seeds it is
wide, and the project reports learned agents with at least 5.

:func:`train_seeds` is made of pieces a hyperparameter sweep (:mod:`dss14_env.agents.sweep`)
runs once per point: :func:`open_campaign` (the folder), :func:`seed_items` (the work items of
:func:`train_one_seed`) and :func:`write_summary` (``summary.json`` and the curves).
"""

from __future__ import annotations

import glob
import json
import re
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dss14_env.agents.campaign_report import (
    REFERENCES,
    reference_scores,
    summary_markdown,
    task_scores,
    validation_references,
)
from dss14_env.agents.config import MAX_SEED, TrainConfig, as_config
from dss14_env.agents.envs import check_env, resolve_env
from dss14_env.agents.evaluation import (
    DEFAULT_SCENARIOS,
    FINAL_SCORING,
    TEST_SEEDS,
    TEST_STEPS,
    EvalTask,
    FinalScoring,
    check_unsealed,
    dss14_tasks,
)
from dss14_env.agents.policy import load_policy
from dss14_env.agents.results import SCENARIO_COLUMNS, column_summary, column_values
from dss14_env.agents.train import evaluation_ranks, last_checkpoint, train, validation_tasks
from dss14_env.core.arrays import read_arrays
from dss14_env.core.files import read_json, read_text
from dss14_env.core.outdir import (
    atomic_save_figure,
    atomic_write_text,
    manifest_kept,
    prepare_output_dir,
    remove_run_files,
    reopen_output_dir,
    update_manifest,
)
from dss14_env.core.parallel import Executor, SerialExecutor, pinned_threads
from dss14_env.core.progress import eta_seconds, format_duration
from dss14_env.core.schema import MAX_CONFIG_BYTES, load_yaml
from dss14_env.core.seeds import parse_seed_list
from dss14_env.core.stats import iqm_ci
from dss14_env.core.text import counted

#: distance between the training seeds of two seed indices
SEED_STRIDE = 1000
#: the command a campaign's (and a sweep's) folder belongs to (its manifest's)
COMMAND = "train --seeds"
#: what a campaign or a sweep (:mod:`dss14_env.agents.sweep`) owns in its folder: either one
#: replaces the other's files (with ``overwrite``), so the results of the two never mix
CAMPAIGN_FILES = ("seed_*", "summary.json", "summary.md", "curves_*.png", "config.yaml", "sweep.json",
                  "sweep.md")
#: seed of the bootstrap resampling (reproducible intervals)
BOOTSTRAP_SEED = 0


def parse_seeds(values: Sequence[str | int]) -> list[int]:
    """Seed indices from ``--train-seeds`` values: ``["0-4"]`` -> 0..4, ``["0", "3", "7"]``
    (:func:`dss14_env.core.seeds.parse_seed_list`, the grammar of ``--seeds`` in every command).

    :raises ValueError: a value that is not an index or a range, a repeated index (naming
        ``--train-seeds``)
    """
    return parse_seed_list(values, option="--train-seeds")


def training_seed(config: TrainConfig, k: int) -> int:
    """The training seed of seed index ``k``: ``config.seed + SEED_STRIDE * k``."""
    return config.seed + SEED_STRIDE * int(k)


def check_training_seeds(cfg: TrainConfig, seeds: Sequence[int]) -> None:
    """Refuse seed indices whose training seed (:func:`training_seed`) passes the largest seed
    (:data:`~dss14_env.agents.config.MAX_SEED`), before any work.

    :raises ValueError: naming ``--train-seeds``
    """
    for k in seeds:
        s = training_seed(cfg, k)
        if s + cfg.n_envs - 1 > MAX_SEED:
            raise ValueError(f"--train-seeds: seed index {k} trains with seed {cfg.seed} + "
                             f"{SEED_STRIDE} x {k} = {s} (and its {cfg.n_envs} sub-environments "
                             f"the next ones), past the largest seed {MAX_SEED}")


def campaign_tasks(cfg: TrainConfig) -> list[EvalTask]:
    """The test tasks of a configuration: the DSS14 scenarios of ``test_scenarios`` (default
    the two holds), or the configured environment.

    :raises ValueError: ``test_scenarios`` other than the default for an environment that is
        not DSS14
    """
    plan = resolve_env(cfg)
    if plan.dss14:
        return dss14_tasks(scenarios=cfg.test_scenarios)
    if tuple(cfg.test_scenarios) != DEFAULT_SCENARIOS:
        raise ValueError(f"{cfg.source}: key 'test_scenarios': the benchmark's scenarios are "
                         f"DSS14 tasks, {cfg.env_id!r} is not a DSS14 environment")
    return [EvalTask("eval", cfg.env_id, {**cfg.env_kwargs, **cfg.eval_env_kwargs})]


def _score(policy_dir: Path, tasks: list[EvalTask], seeds: Sequence[int],
           steps: int | None, access: FinalScoring | None) -> dict[str, Any]:
    return task_scores(load_policy(policy_dir), tasks, seeds, steps, access)


def _aggregate(values: list[float]) -> dict[str, Any]:
    est = iqm_ci(values, np.random.default_rng(BOOTSTRAP_SEED))
    return {"iqm": est.as_dict(), "mean": float(np.mean(values)), "min": float(np.min(values)),
            "max": float(np.max(values)), "per_seed": [float(v) for v in values]}


def _as_yaml_data(cfg: TrainConfig) -> Any:
    return load_yaml(yaml.safe_dump(cfg.to_dict(), sort_keys=False), cfg.source)


def finished_run(cfg: TrainConfig, run: Path) -> bool:
    """Whether ``run`` holds a finished training run of ``cfg``: its ``train_summary.json``
    (written last) reports at least ``cfg.total_timesteps`` steps and its ``config.yaml``
    is ``cfg``.
    """
    try:
        ts = read_json(run / "train_summary.json")
        saved = load_yaml(read_text(run / "config.yaml", MAX_CONFIG_BYTES), str(run / "config.yaml"))
    except (OSError, ValueError):
        return False
    return saved == _as_yaml_data(cfg) and int(ts.get("num_timesteps", -1)) >= cfg.total_timesteps


def check_saved_config(cfg: TrainConfig, folder: Path) -> None:
    """Refuse to continue in ``folder`` unless its ``config.yaml`` is ``cfg``.

    :raises ValueError: no readable ``config.yaml``, or another configuration (``--resume``)
    """
    try:
        saved = load_yaml(read_text(folder / "config.yaml", MAX_CONFIG_BYTES), str(folder / "config.yaml"))
    except (OSError, ValueError):
        raise ValueError(f"--resume: {folder} holds no campaign to continue (no readable "
                         f"config.yaml)") from None
    if saved != _as_yaml_data(cfg):
        raise ValueError(f"--resume: {folder / 'config.yaml'} is another configuration than "
                         f"{cfg.source}; continue with the campaign's own --config")


def _continue_campaign(cfg: TrainConfig, out: str | Path, seeds: Sequence[int]) -> tuple[Path, set[int]]:
    """The folder of the interrupted campaign and the seed indices whose run finished; the
    unfinished seeds' folders and the campaign's summary and curves are removed.
    """
    folder = Path(out)
    check_saved_config(cfg, folder)
    reopen_output_dir(folder, owned_files(folder), "--out", command=COMMAND)
    remove_run_files(folder, ("summary.json", "summary.md", "curves_*.png"))
    finished = set()
    for k in seeds:
        run, seed_cfg = folder / f"seed_{k}", cfg.replace(seed=training_seed(cfg, k))
        if finished_run(seed_cfg, run):
            finished.add(k)
        elif run.exists() and resumable_checkpoint(seed_cfg, run) is None:
            remove_run_files(folder, (run.name,))
    return folder, finished


def resumable_checkpoint(cfg: TrainConfig, run: Path) -> Path | None:
    """The last checkpoint of an unfinished run of ``cfg`` (its ``config.yaml`` is ``cfg``) before
    its last step, which the run continues from; None: no such run or no such checkpoint (it
    trains anew).
    """
    try:
        saved = load_yaml(read_text(run / "config.yaml", MAX_CONFIG_BYTES), str(run / "config.yaml"))
    except (OSError, ValueError):
        return None
    return last_checkpoint(run, before=cfg.total_timesteps) if saved == _as_yaml_data(cfg) else None


def kept_work(cfg: TrainConfig, folder: str | Path, seeds: Sequence[int]) -> str:
    """What an interrupted campaign keeps, per seed index: ``seed_0 finished, seed_1 at 1536
    steps (checkpoints/1536_steps), seed_2 nothing yet``.
    """
    parts = []
    for k in seeds:
        run, seed_cfg = Path(folder) / f"seed_{k}", cfg.replace(seed=training_seed(cfg, k))
        ckpt = None if finished_run(seed_cfg, run) else resumable_checkpoint(seed_cfg, run)
        state = ("finished" if finished_run(seed_cfg, run) else
                 f"at {ckpt.name[:-6]} steps ({ckpt.parent.name}/{ckpt.name})" if ckpt is not None
                 else "nothing yet")
        parts.append(f"{run.name} {state}")
    return ", ".join(parts)


def owned_files(folder: str | Path) -> tuple[str, ...]:
    """What a campaign or a sweep owns in ``folder``: :data:`CAMPAIGN_FILES` and, when the
    folder's ``config.yaml`` is a sweep's, the folders of its points (named from that file, so
    nothing else in the folder is ever taken for a point).
    """
    saved = Path(folder) / "config.yaml"
    if not saved.is_file():
        return CAMPAIGN_FILES
    try:
        cfg = as_config(saved)
    except (OSError, ValueError):
        return CAMPAIGN_FILES
    points = cfg.points() if cfg.sweep else []
    return CAMPAIGN_FILES + tuple(glob.escape(p.label) for p in points)


def open_campaign(cfg: TrainConfig, out: str | Path, seeds: Sequence[int], overwrite: bool = False,
                  resume: bool = False, owned: Sequence[str] | None = None) -> tuple[Path, set[int]]:
    """Make (or, with ``resume``, reopen) a campaign folder before any training.

    A new campaign's folder is checked (:func:`~dss14_env.core.outdir.prepare_output_dir` with
    ``owned``) and gets the shared ``config.yaml``; an interrupted one keeps its finished runs.

    :return: the folder and the seed indices whose run finished (empty for a new campaign)
    :raises ValueError: an unusable folder, earlier results without ``overwrite``, or (with
        ``resume``) a folder of another configuration
    """
    if resume:
        return _continue_campaign(cfg, out, seeds)
    folder = prepare_output_dir(out, owned_files(out) if owned is None else owned, overwrite, "--out",
                                command=COMMAND)
    atomic_write_text(folder / "config.yaml", f"# shared configuration of the campaign (from "
                      f"{cfg.source}); run k trains with seed {cfg.seed} + {SEED_STRIDE} k\n"
                      + yaml.safe_dump(cfg.to_dict(), sort_keys=False))
    update_manifest(folder)
    return folder, set()


def seed_items(cfg: TrainConfig, folder: Path, seeds: Sequence[int], finished: set[int],
               test_seeds: Sequence[int], test_steps: int,
               progress: bool | None = None, final_scoring: bool = False) -> list[dict[str, Any]]:
    """The work items of a campaign, one per seed index (:func:`train_one_seed`).

    :param progress: each run's steps on stderr (:func:`~dss14_env.agents.train.train`'s
        ``progress``; None: the configuration's ``progress_bar``)
    :param final_scoring: the items' test scores are the final scoring (a campaign: it may
        read the sealed test seeds); False: research (a sweep), refused them
    """
    return [{"config": cfg, "k": int(k), "folder": str(folder),
             "test_seeds": [int(s) for s in test_seeds], "test_steps": int(test_steps),
             "finished": k in finished, "progress": progress, "final_scoring": bool(final_scoring)}
            for k in seeds]


def check_folder_first(cfg: TrainConfig, out: str | Path, overwrite: bool, resume: bool,
                       owned: Sequence[str] | None = None) -> None:
    """Refuse an unusable campaign (or sweep) folder at once, before the campaign's first line
    and its environment check: checked only, nothing made or removed (:func:`open_campaign`
    opens it after the checks).

    :raises ValueError: as :func:`open_campaign` (with ``resume``: no campaign of ``cfg`` there)
    """
    if resume:
        check_saved_config(cfg, Path(out))
    else:
        prepare_output_dir(out, owned_files(out) if owned is None else owned, overwrite, "--out",
                           dry_run=True, command=COMMAND)


def say_plan(cfg: TrainConfig, folder: str | Path, runs: int, resume: bool = False) -> None:
    """The campaign's first line on stderr, before its environment is checked and any model is
    built (seconds): what it trains, how long a run, where.  Each run then says as it starts
    whether it trains, continues from a checkpoint or finished earlier.
    """
    what = f"continuing {counted(runs, 'run')}" if resume else counted(runs, "run")
    print(f"{cfg.algo} on {cfg.env_id}: {what} of {cfg.total_timesteps} steps into {folder}",
          file=sys.stderr, flush=True)


def run_seed_items(executor: Executor, items: Sequence[Mapping[str, Any]],
                   labels: Sequence[str]) -> dict[int, dict[str, Any]]:
    """Run :func:`train_one_seed` over ``items``; say on stderr as each one ends, with the
    campaign's elapsed time and its ETA (at the rate of the items so far).

    :return: item index -> the item's entry
    """
    t0, done = time.monotonic(), {}
    for i, entry in executor.map_unordered(train_one_seed, items, labels=labels):
        done[i] = entry
        elapsed = time.monotonic() - t0
        left = len(items) - len(done)
        eta = eta_seconds(len(done), len(items), elapsed)
        tail = (f", ETA {format_duration(eta)} for the other {counted(left, 'run')}"
                if left and eta is not None else "")
        print(f"{labels[i]}: done ({len(done)} of {len(items)}), campaign {format_duration(elapsed)} "
              f"elapsed{tail}", file=sys.stderr, flush=True)
    return done


def train_one_seed(item: Mapping[str, Any]) -> dict[str, Any]:
    """One seed index of :func:`train_seeds`: train into ``<folder>/seed_<k>/`` (or, with
    ``finished``, take the run there), then score the final and best policies -- one work item
    of an executor (:mod:`dss14_env.core.parallel`).

    :param item: ``config`` (:class:`TrainConfig`), ``k``, ``folder``, ``test_seeds``,
        ``test_steps``, optional ``finished``
    :return: the seed's entry of ``summary.json``'s ``per_seed``
    """
    cfg, k = as_config(item["config"]), int(item["k"])
    tasks, test_seeds, test_steps = campaign_tasks(cfg), item["test_seeds"], item["test_steps"]
    access = FINAL_SCORING if item.get("final_scoring", False) else None
    check_unsealed(test_seeds, access, f"{Path(item['folder']).name}/seed_{k}: test scoring")
    run, seed_cfg = Path(item["folder"]) / f"seed_{k}", cfg.replace(seed=training_seed(cfg, k))
    if item.get("finished", False):
        print(f"{run.name}: finished earlier, scored again", file=sys.stderr, flush=True)
    else:
        ckpt = resumable_checkpoint(seed_cfg, run) if run.is_dir() else None
        print(f"{run.name}: " + (f"training {seed_cfg.total_timesteps} steps" if ckpt is None else
                                 f"continuing from {ckpt.parent.name}/{ckpt.name} to "
                                 f"{seed_cfg.total_timesteps} steps")
              + f" into {run} (training seed {seed_cfg.seed})", file=sys.stderr, flush=True)
        run = train(seed_cfg, run_dir=run, resume=ckpt, progress=item.get("progress"))
    ts = read_json(run / "train_summary.json")
    entry: dict[str, Any] = {"seed_index": k, "training_seed": training_seed(cfg, k),
                             "run": run.name, "wall_s": ts["wall_s"],
                             "env_steps": ts["num_timesteps"]}
    entry["final"] = _score(run, tasks, test_seeds, test_steps, access)
    best = run / "eval" / "best"
    entry["best"] = _score(best, tasks, test_seeds, test_steps, access) if best.is_dir() else None
    if entry["best"] is None and (run / "eval" / "evaluations.npz").is_file():
        # every validation disqualified the policy (a termination, or with select_by general a
        # step that never settles): the seed's selected policy is its final one
        entry["best"], entry["best_is_final"] = entry["final"], True
    return entry


def write_summary(cfg: TrainConfig, folder: Path, seeds: Sequence[int], per_seed: list[dict[str, Any]],
                  test_seeds: Sequence[int], test_steps: int, figures: bool = True,
                  references: bool = True, access: FinalScoring | None = None) -> dict[str, Any]:
    """Write a campaign's ``summary.json``, ``summary.md`` (and learning curves) from its
    seeds' entries.

    :param per_seed: :func:`train_one_seed`'s entries, in the order of ``seeds``
    :param references: score the reference controllers (PI, LQG) on the same test episodes
        and validation episodes (DSS14; the summary's and the curves' references)
    :param access: :data:`~dss14_env.agents.evaluation.FINAL_SCORING` when the test seeds are
        the sealed ones and this is the final scoring (a campaign), else None
    :return: the summary
    """
    tasks = campaign_tasks(cfg)
    aggregate: dict[str, Any] = {}
    for which in ("final", "best"):
        rows = [e[which] for e in per_seed if e[which] is not None]
        if len(rows) != len(per_seed):
            continue
        aggregate[which] = {}
        for t in tasks:
            key = "mean_three_sigma_mdeg" if t.axis is not None else "mean_return"
            aggregate[which][t.name] = {"metric": key,
                                        **_aggregate([r[t.name][key] for r in rows])}
            if t.pointing_axis is not None:
                aggregate[which][t.name]["pointing"] = {
                    "metric": "mean_pointing_three_sigma_mdeg",
                    **_aggregate([r[t.name]["mean_pointing_three_sigma_mdeg"] for r in rows])}
            if t.name in SCENARIO_COLUMNS and all("figures" in r[t.name] for r in rows):
                aggregate[which][t.name]["figures"] = {
                    col: column_summary(np.array([column_values(t.name, col, r[t.name]["figures"])
                                                  for r in rows]), col,
                                        np.random.default_rng(BOOTSTRAP_SEED))
                    for col, _ in SCENARIO_COLUMNS[t.name]}
    val_tasks = validation_tasks(cfg)
    refs: dict[str, Any] = {}
    if references and any(t.preset is not None for t in tasks):
        refs = {"controllers": {k: v[0] for k, v in REFERENCES.items()},
                "test": reference_scores(tasks, test_seeds, test_steps, access),
                "validation": validation_references(val_tasks, cfg.eval_seeds, cfg.eval_episode_steps,
                                                    cfg.n_eval_episodes)}
    summary = {
        "algo": cfg.algo, "env_id": cfg.env_id, "config": cfg.source,
        "seed_indices": list(seeds), "training_seeds": [training_seed(cfg, k) for k in seeds],
        "protocol": {"test_seeds": [int(s) for s in test_seeds], "test_steps": int(test_steps),
                     "tasks": [{"name": t.name, "env_id": t.env_id, "axis": t.axis,
                                "pointing_axis": t.pointing_axis,
                                "warmup_steps": t.warmup_steps,
                                "steps": test_steps if t.axis is not None else t.steps} for t in tasks],
                     "validation_seeds": cfg.eval_seeds,
                     "interval": "95 % percentile bootstrap over training seeds of the IQM "
                                 "(dss14_env.core.stats.iqm_ci)"},
        "per_seed": per_seed, "aggregate": aggregate,
    }
    if refs:
        summary["references"] = refs
    atomic_write_text(folder / "summary.json", json.dumps(summary, indent=2) + "\n")
    atomic_write_text(folder / "summary.md", summary_markdown(summary))
    if figures:
        write_curves(folder, [folder / f"seed_{k}" for k in seeds], val_tasks, refs.get("validation"))
    update_manifest(folder)
    return summary


def train_seeds(config: TrainConfig | Mapping[str, Any] | str | Path, seeds: Sequence[int],
                out: str | Path, overwrite: bool = False, test_seeds: Sequence[int] = TEST_SEEDS,
                test_steps: int = TEST_STEPS, figures: bool = True,
                executor: Executor | None = None, resume: bool = False,
                progress: bool | None = None) -> Path:
    """Train one run per seed index and score them (see the module doc).

    :param config: the shared configuration (its ``seed`` is the base seed; a sweep:
        :func:`dss14_env.agents.sweep.train_sweep`)
    :param seeds: seed indices ``k``
    :param out: the campaign folder (checked before any work; ``overwrite`` replaces an
        earlier campaign's files)
    :param test_seeds: evaluation seeds, default 0-9 (never used in training)
    :param test_steps: episode length of the test episodes, default 3000 (60 s)
    :param figures: draw the learning curves
    :param executor: where the seeds run (:mod:`dss14_env.core.parallel`): default one after
        another in this process; a Ray executor runs them as Ray tasks (the same numbers: every
        seed runs with one BLAS thread either way); ``out`` must then be a folder every Ray node
        can write
    :param resume: continue the interrupted campaign in ``out`` (same configuration): the seeds
        whose run finished are scored, not retrained; the others continue from their last
        checkpoint (or train anew without one)
    :param progress: each run's steps on stderr (None: the configuration's ``progress_bar``);
        a line as each seed starts and ends (with the campaign's ETA) either way
    :return: the campaign folder
    :raises ValueError: a sweep configuration (before any work)
    """
    cfg = as_config(config)
    if cfg.sweep:
        raise ValueError(f"{cfg.source}: field 'sweep': a sweep trains one campaign per point "
                         f"(dss14_env.agents.sweep.train_sweep)")
    seeds = [int(k) for k in seeds]
    check_training_seeds(cfg, seeds)
    campaign_tasks(cfg)  # an environment the tasks cannot be made of: before any work
    check_folder_first(cfg, out, overwrite, resume)
    say_plan(cfg, out, len(seeds), resume)
    with pinned_threads(1):  # a training environment that cannot be made: before any work
        check_env(cfg)
    folder, finished = open_campaign(cfg, out, seeds, overwrite, resume)
    with manifest_kept(folder):
        items = seed_items(cfg, folder, seeds, finished, test_seeds, test_steps, progress,
                           final_scoring=True)
        ex = executor if executor is not None else SerialExecutor()
        done = run_seed_items(ex, items, [f"seed_{k}" for k in seeds])
        write_summary(cfg, folder, seeds, [done[i] for i in range(len(seeds))], test_seeds,
                      test_steps, figures, access=FINAL_SCORING)
    return folder


def is_campaign_folder(path: str | Path) -> bool:
    """A training campaign's folder (``seed_<k>/`` runs) rather than a policy folder."""
    p = Path(path)
    return p.is_dir() and not (p / "policy.pt").is_file() and any(
        d.is_dir() and re.fullmatch(r"seed_\d+", d.name) for d in p.iterdir())


def selected_evaluation(history: str | Path) -> tuple[int, tuple[bool, float]] | None:
    """The evaluation ``eval/best`` holds, from a run's ``eval/evaluations.npz``: its index
    and rank ``(beats the selection's reference on every validation task, selection score)``
    -- the highest rank, as the training's evaluator keeps it (:func:`evaluation_ranks`); None
    without scores.
    """
    d = read_arrays(history)
    if "selection_score" not in d or not d["selection_score"].size:
        return None
    ranks = evaluation_ranks(d["selection_score"].tolist(), d["selection_qualified"].tolist()
                             if "selection_qualified" in d else None)
    i = max(range(len(ranks)), key=lambda k: ranks[k])  # the first of equal ranks, as kept
    return i, ranks[i]


def best_seed_policy(folder: str | Path) -> tuple[Path, str]:
    """The policy a training campaign folder stands for: ``seed_<k>/eval/best`` of the seed
    whose validation-selected policy has the best validation score (:func:`selection_score`
    in ``eval/evaluations.npz``: validation seeds only, never the test seeds); with
    ``select_reference``, a seed whose selected policy beats the reference on every validation
    task ranks before any that does not.

    :return: the policy folder and a one-line note saying which seed and why
    :raises ValueError: no seed of the folder has an ``eval/best`` with its scores
    """
    folder = Path(folder)
    ranks: dict[Path, tuple[bool, float]] = {}
    for run in sorted(folder.glob("seed_*"), key=lambda d: int(d.name[5:]) if d.name[5:].isdigit() else -1):
        hist = run / "eval" / "evaluations.npz"
        if not ((run / "eval" / "best" / "policy.pt").is_file() and hist.is_file()):
            continue
        sel = selected_evaluation(hist)
        if sel is not None:
            ranks[run] = sel[1]
    if not ranks:
        raise ValueError(f"--ppo-model: {folder} is a training campaign folder without a seed's "
                         f"eval/best and its validation scores; give a policy folder (e.g. "
                         f"{folder}/seed_0/eval/best)")
    best = max(ranks, key=lambda r: ranks[r])
    beats = " (it beats the selection's reference on every validation task)" if ranks[best][0] else ""
    note = (f"--ppo-model: {folder} is a training campaign: using {best.name}/eval/best, the best "
            f"validation score of its {counted(len(ranks), 'seed')} "
            f"({ranks[best][1]:.4g}){beats}; the campaign's figures over all seeds are in its summary.json")
    return best / "eval" / "best", note


def learning_curves(runs: Sequence[Path], task: str) -> dict[str, Any]:
    """Validation curves of several runs on a common step grid (the steps all runs share).

    :return: ``steps``, ``three_sigma``, ``pointing`` (3σ pointing error) and ``returns`` as
        ``(n_runs, n_steps)`` (mean over the validation seeds; NaN where a run has no such value)
    """
    entries = {"three_sigma": "three_sigma_mdeg", "pointing": "pointing_three_sigma_mdeg"}
    data = []
    for r in runs:
        d = read_arrays(r / "eval" / "evaluations.npz")
        errs = {k: d[f"{v}_{task}"] for k, v in entries.items() if f"{v}_{task}" in d}
        data.append((d["timesteps"].astype(int), np.asarray(d[f"returns_{task}"]), errs))
    common = sorted(set.intersection(*(set(t.tolist()) for t, _, _ in data))) if data else []
    steps = np.array(common, int)
    out = {"steps": steps, "returns": np.full((len(data), steps.size), np.nan)}
    out.update({k: np.full((len(data), steps.size), np.nan) for k in entries})
    for i, (t, r, errs) in enumerate(data):
        idx = [int(np.flatnonzero(t == x)[0]) for x in common]
        out["returns"][i] = r[idx].mean(axis=1)
        for k, v in errs.items():
            out[k][i] = np.nanmean(v[idx], axis=1)
    return out


def _band(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    mid, lo, hi = [], [], []
    for col in values.T:
        e = iqm_ci(col, rng)
        mid.append(e.value)
        lo.append(e.low)
        hi.append(e.high)
    return np.array(mid), np.array(lo), np.array(hi)


#: line styles of the reference controllers in the learning curves
_REFERENCE_STYLES = {"pi_kp1": ("k", "--"), "lqg": ("tab:red", ":")}


def _reference_lines(ax: Any, references: Mapping[str, Any] | None, task: str, key: str) -> None:
    """The references' mean validation 3σ of one panel as horizontal lines."""
    for name, by_task in (references or {}).items():
        v = by_task.get(task, {}).get(key)
        if v is not None and np.isfinite(v):
            color, style = _REFERENCE_STYLES.get(name, ("0.3", "-."))
            ax.axhline(v, color=color, ls=style, lw=1.2,
                       label=f"{REFERENCES[name][0] if name in REFERENCES else name}: {v:.3g}")


def write_curves(folder: Path, runs: Sequence[Path], tasks: Sequence[EvalTask],
                 references: Mapping[str, Mapping[str, Mapping[str, float | None]]] | None = None
                 ) -> list[Path]:
    """One PNG per validation task: validation 3σ servo error (DSS14), 3σ pointing error (where
    the runs recorded it) and return vs environment steps (IQM over the runs with its 95 %
    bootstrap band, each run thin), with the reference controllers' mean 3σ on the same
    validation episodes as horizontal lines.

    :param references: name -> task -> ``three_sigma``, ``pointing``
        (:func:`~dss14_env.agents.campaign_report.validation_references`); None: no lines
    :return: the files written (none when a run has no validation history: ``eval_freq`` 0)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    written: list[Path] = []
    if not all((r / "eval" / "evaluations.npz").is_file() for r in runs):  # eval_freq 0: no curves
        return written
    for t in tasks:
        c = learning_curves(runs, t.name)
        if c["steps"].size == 0:
            continue
        panels = [("returns", "validation return")]
        if t.pointing_axis is not None and np.isfinite(c["pointing"]).any():
            panels.insert(0, ("pointing", f"validation 3σ pointing error {t.pointing_axis} (mdeg)"))
        if t.axis is not None:
            panels.insert(0, ("three_sigma", f"validation 3σ servo error {t.axis} (mdeg)"))
        fig = Figure(figsize=(6.0 * len(panels), 4.0))
        FigureCanvasAgg(fig)
        for j, (key, label) in enumerate(panels):
            ax = fig.add_subplot(1, len(panels), j + 1)
            v = c[key]
            for row in v:
                ax.plot(c["steps"], row, color="0.7", lw=0.8)
            mid, lo, hi = _band(v)
            ax.fill_between(c["steps"], lo, hi, alpha=0.3, label="95 % bootstrap CI")
            ax.plot(c["steps"], mid, lw=2, label=f"IQM over {counted(len(runs), 'seed')}")
            _reference_lines(ax, references, t.name, key)
            ax.set_xlabel("environment steps")
            pos = v[np.isfinite(v) & (v > 0)]
            if key != "returns" and pos.size and pos.max() > 20.0 * pos.min():
                ax.set_yscale("log")  # early divergent evaluations would flatten the rest
                label += ", log scale"
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        fig.suptitle(f"{t.name}: learning curves")
        path = folder / f"curves_{t.name}.png"
        atomic_save_figure(fig, path, dpi=100)
        written.append(path)
    return written


__all__ = ["CAMPAIGN_FILES", "SEED_STRIDE", "campaign_tasks", "check_folder_first", "check_saved_config",
           "check_training_seeds", "finished_run", "kept_work", "resumable_checkpoint", "run_seed_items",
           "say_plan", "owned_files",
           "best_seed_policy", "is_campaign_folder", "learning_curves", "open_campaign", "parse_seeds",
           "seed_items", "train_one_seed", "train_seeds",
           "training_seed", "write_curves", "write_summary"]
