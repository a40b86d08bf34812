"""A training campaign's test scores, its references and its ``summary.md``.

:func:`task_scores` scores a controller on a campaign's test tasks (``summary.json``'s
entries); :func:`reference_scores` scores the bench's report PI and LQG (:data:`REFERENCES`, the
catalog's rows of the same names) on a campaign's test tasks and seeds exactly as its policies
are scored (:func:`dss14_env.agents.campaign.task_scores`: the same episodes, lengths and
figures), :func:`validation_references` their mean 3σ on the validation tasks and seeds (the
reference lines of the learning curves), and :func:`summary_markdown` renders a campaign's
``summary.json`` as ``summary.md``: per training seed the test figures of its
validation-selected policy (the final one in brackets), the interquartile mean over the training
seeds with its 95 % bootstrap interval, and the references' means over the same test seeds with
theirs (:func:`dss14_env.agents.results.column_summary`, the statistics of the RL table).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from dss14_env.agents.evaluation import FIGURES, EvalTask, FinalScoring, run_task, task_env
from dss14_env.agents.results import SCENARIO_COLUMNS, column_summary, column_values, summary_cell
from dss14_env.core.text import counted

#: the reference controllers of a campaign: name -> (label, module, class, arguments after the
#: environment), the bench's catalog rows of the same names (tests hold them equal)
REFERENCES: Mapping[str, tuple[str, str, str, tuple[Any, ...]]] = {
    "pi_kp1": ("PI (report: kp 1, ki 0.3)", "dss14_env.baselines.pi", "PIController", ("kp1",)),
    "lqg": ("LQG", "dss14_env.baselines.lqg", "LQGController", ()),
}
#: seed of the summary's bootstrap resampling (the campaign's)
BOOTSTRAP_SEED = 0


def task_scores(ctrl: Any, tasks: Sequence[EvalTask], seeds: Sequence[int],
                steps: int | None, access: FinalScoring | None = None) -> dict[str, Any]:
    """A controller's test scores per task, the entry of ``summary.json`` (a hold task runs
    ``steps`` steps, any other its own length, :func:`~dss14_env.agents.evaluation.run_task`):
    returns, terminations, the 3σ of the task's axes and, for a DSS14 task, ``figures``: every
    episode's figures (:data:`~dss14_env.agents.evaluation.FIGURES` that the scenario has,
    ``terminated`` and ``command_hf_share``), those of the bench's episode records.
    ``access``: the final scoring's token for the sealed test seeds
    (:func:`~dss14_env.agents.evaluation.check_unsealed`).
    """
    out = {}
    for t in tasks:
        r = run_task(ctrl, t, seeds, steps if t.axis is not None else None, access=access)
        d = {"returns": r["returns"].tolist(), "mean_return": float(np.mean(r["returns"])),
             "terminated": int(r["terminated"].sum())}
        if t.axis is not None:
            d["axis"] = t.axis
            d["three_sigma_mdeg"] = r["three_sigma_mdeg"].tolist()
            d["mean_three_sigma_mdeg"] = float(np.mean(r["three_sigma_mdeg"]))
        if t.pointing_axis is not None:
            d["pointing_axis"] = t.pointing_axis
            d["pointing_three_sigma_mdeg"] = r["pointing_three_sigma_mdeg"].tolist()
            d["mean_pointing_three_sigma_mdeg"] = float(np.mean(r["pointing_three_sigma_mdeg"]))
        if t.preset is not None:
            d["figures"] = {k: r[k].tolist() for k in FIGURES if not np.isnan(r[k]).all()}
            d["figures"]["terminated"] = r["terminated"].tolist()
            d["figures"]["command_hf_share"] = r["command_hf_share"].tolist()
        out[t.name] = d
    return out


def reference_controller(name: str, env: Any) -> Any:
    """The reference controller ``name`` of :data:`REFERENCES` built on ``env``."""
    _, module, cls, args = REFERENCES[name]
    return getattr(importlib.import_module(module), cls)(env, *args)


def reference_scores(tasks: Sequence[EvalTask], seeds: Sequence[int], steps: int | None,
                     access: FinalScoring | None = None) -> dict[str, Any]:
    """Every reference's test scores on the DSS14 tasks (built per task on its environment, as
    the bench builds them per scenario), in the form of a policy's (:func:`task_scores`;
    ``access`` as there); empty without DSS14 tasks.
    """
    out: dict[str, Any] = {}
    for name in REFERENCES:
        for t in tasks:
            if t.preset is None:
                continue
            env = task_env(t)
            try:
                out.setdefault(name, {}).update(task_scores(reference_controller(name, env), [t], seeds,
                                                            steps, access))
            finally:
                env.close()
    return out


def validation_references(tasks: Sequence[EvalTask], seeds: Sequence[int], steps: int,
                          n_episodes: int = 1) -> dict[str, Any]:
    """Every reference's mean 3σ servo and pointing errors on the validation tasks with an axis
    (the learning curves' reference lines): name -> task -> ``three_sigma``, ``pointing``.
    """
    out: dict[str, Any] = {}
    holds = [t for t in tasks if t.axis is not None]
    for name in REFERENCES:
        for t_name, r in reference_runs(name, holds, seeds, steps, n_episodes).items():
            pointing_axis = next(t.pointing_axis for t in holds if t.name == t_name)
            out.setdefault(name, {})[t_name] = {
                "three_sigma": float(np.mean(r["three_sigma_mdeg"])),
                "pointing": float(np.mean(r["pointing_three_sigma_mdeg"])) if pointing_axis else None}
    return out


def reference_runs(name: str, tasks: Sequence[EvalTask], seeds: Sequence[int], steps: int | None,
                   n_episodes: int = 1) -> dict[str, dict[str, Any]]:
    """The :func:`run_task` results of the reference ``name`` on each DSS14 task (built per task
    on its environment, as the bench builds it): the holds ``steps`` long, the other scenarios
    in their own lengths.
    """
    out: dict[str, dict[str, Any]] = {}
    for t in tasks:
        if t.preset is None:
            continue
        env = task_env(t)
        try:
            out[t.name] = run_task(reference_controller(name, env), t, seeds,
                                   steps if t.axis is not None else None, n_episodes)
        finally:
            env.close()
    return out


#: a summary column: head, statistic kind (``value`` or a column of ``SCENARIO_COLUMNS``),
#: per-episode values of a task's scores
Column = tuple[str, str, Callable[[Mapping[str, Any]], np.ndarray]]


def summary_columns(task: Mapping[str, Any]) -> list[Column]:
    """The summary's columns of one task of ``summary.json``'s protocol: (head, statistic kind,
    per-episode values of a task's scores); holds: 3σ servo and pointing errors; track, step,
    slew: :data:`~dss14_env.agents.results.SCENARIO_COLUMNS`; any other: the return.
    """
    name = task["name"]
    if task.get("axis"):
        cols = [(f"{name} {task['axis']} servo 3σ (mdeg)", "value",
                 lambda d: np.asarray(d["three_sigma_mdeg"], float))]
        if task.get("pointing_axis"):
            cols.append((f"{name} {task['pointing_axis']} pointing 3σ (mdeg)", "value",
                         lambda d: np.asarray(d["pointing_three_sigma_mdeg"], float)))
        return cols
    if name in SCENARIO_COLUMNS:
        return [(head, col, lambda d, c=col: column_values(name, c, d["figures"]))
                for col, head in SCENARIO_COLUMNS[name]]
    return [(f"{name} return", "value", lambda d: np.asarray(d["returns"], float))]


def _seed_cell(col: str, best: np.ndarray, final: np.ndarray | None) -> str:
    def one(x: np.ndarray) -> str:
        if col == "terminated":
            return f"{int(np.nansum(x))}"
        return f"{np.mean(x):.3g}" if np.isfinite(x).all() else "∞" if np.isposinf(x).any() else "–"

    return one(best) + ("" if final is None else f" ({one(final)})")


def summary_markdown(summary: Mapping[str, Any]) -> str:
    """``summary.md`` of a campaign's ``summary.json`` (see the module doc)."""
    tasks = summary["protocol"]["tasks"]
    seeds = summary["protocol"]["test_seeds"]
    per_seed = summary["per_seed"]
    cols = [(t["name"], head, col, get) for t in tasks for head, col, get in summary_columns(t)]
    head = ["", *(h for _, h, _, _ in cols)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    which = "best" if all(e.get("best") is not None for e in per_seed) else "final"
    for e in per_seed:
        cells = [f"seed {e['seed_index']} ({e['training_seed']})"]
        for task, _, col, get in cols:
            final = get(e["final"][task]) if which == "best" else None
            cells.append(_seed_cell(col, get(e[which][task]), final))
        lines.append("| " + " | ".join(cells) + " |")
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    iqm = [f"IQM over {counted(len(per_seed), 'training seed')}"]
    for task, _, col, get in cols:
        x = np.array([get(e[which][task]) for e in per_seed])
        iqm.append(summary_cell(column_summary(x, col, np.random.default_rng(BOOTSTRAP_SEED)), True))
    lines.append("| " + " | ".join(iqm) + " |")
    refs = summary.get("references", {}).get("test", {})
    for name, scores in refs.items():
        cells = [f"{REFERENCES[name][0] if name in REFERENCES else name}, same test seeds"]
        for task, _, col, get in cols:
            cells.append(summary_cell(column_summary(get(scores[task]), col, rng), False)
                         if task in scores else "–")
        lines.append("| " + " | ".join(cells) + " |")
    pick = ("the validation-selected policy (eval/best), the final policy in brackets"
            if which == "best" else "the final policy (no eval/best)")
    finals = [str(e["training_seed"]) for e in per_seed if e.get("best_is_final")]
    if finals and which == "best":
        pick += (f" (training seed{'s' if len(finals) > 1 else ''} {', '.join(finals)}: every validation "
                 f"disqualified the policy -- a termination or a step that never settles -- so the "
                 f"selected policy is the final one)")
    text = (f"# Training campaign: {summary['config']}\n\n"
            f"{summary['algo']} on `{summary['env_id']}`, "
            f"{counted(len(per_seed), 'training seed')} ({', '.join(map(str, summary['training_seeds']))}); "
            f"test seeds {seeds[0]}–{seeds[-1]} (never used in training or selection), "
            f"{summary['protocol']['test_steps']}-step holds, the other scenarios in the bench's "
            f"lengths. Per training seed: {pick}, the mean over the {len(seeds)} test seeds "
            f"(terminated: episodes). IQM: interquartile mean over the training seeds [95 % "
            f"bootstrap interval over training seeds]; references: the bench's controllers on "
            f"the same test episodes, mean [95 % bootstrap interval over test seeds]. "
            f"Step and slew figures on the worse axis; ∞: never settled.\n\n")
    return text + "\n".join(lines) + "\n"


__all__ = ["BOOTSTRAP_SEED", "REFERENCES", "reference_controller", "reference_scores",
           "summary_columns", "summary_markdown", "task_scores", "validation_references"]
