"""The learned agents' results table: training campaigns beside the reference controllers.

Inputs are a training campaign's ``summary.json`` per agent (:mod:`dss14_env.agents.campaign`:
per training seed, the 3σ of every test episode of the final and the validation-selected
policy) and the reference controllers' 3σ on the same test seeds.  :func:`build_results`
turns them into one JSON-ready mapping, :func:`rl_tables` renders its Markdown tables.

Two errors are scored per hold: the servo error at the drive encoders on the loaded axis (the
report's Table 4 quantity: front wind elevation, side wind azimuth) and the dish's true
pointing error on the axis the wind swings (front: elevation, side: cross-elevation,
:data:`POINTING_AXES`).  A campaign whose summary has no pointing scores (one made before they
were recorded) and a reference without them get no pointing entry; the tables show "–".

Statistics (all from seeded generators, :data:`BOOTSTRAP_SEED`):

* an agent's score in a hold is, per training seed, the mean 3σ over the test seeds; over the
  training seeds the interquartile mean with its 95 % percentile-bootstrap interval
  (:func:`dss14_env.core.stats.iqm_ci`, resampling training seeds);
* a reference controller's score is its mean 3σ over the test seeds, with its 95 %
  percentile-bootstrap interval over the test seeds;
* an agent's ratio to a reference, ``IQM_k(mean_j X[k, j]) / mean_j r[j]``, has a two-level
  percentile-bootstrap interval: each resample draws the test seeds ``j`` (the same for the
  agent and the reference: they saw the same gusts) and the training seeds ``k``, so both
  sources of spread are in it (:func:`agent_ratio`); a reference's ratio to another resamples
  the test seeds paired (:func:`dss14_env.core.stats.ratio_ci`).  A ratio whose interval
  contains 1 is marked "not significant".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dss14_env.core.results import POINTING_AXIS_OF, Cell, RatioCell
from dss14_env.core.stats import N_RESAMPLES, bootstrap_ci, iqm, iqm_ci, ratio_ci
from dss14_env.envs.presets import PRESETS

#: the holds of the table and the axis each is scored on (the axis the wind loads: the
#: preset's ``loaded_axes``)
HOLDS = {h: PRESETS[h].loaded_axes[0] for h in ("hold_front", "hold_side")}
#: the pointing-error axis of each hold (the axis the wind swings the dish about)
POINTING_AXES = {h: POINTING_AXIS_OF[axis] for h, axis in HOLDS.items()}
#: salt offset of the pointing statistics' resampling streams (the servo ones keep theirs)
_POINTING_SALT = 10
#: seed of every bootstrap resampling here
BOOTSTRAP_SEED = 0
#: the references every agent is divided by
RATIO_REFERENCES = ("pi_kp1", "lqg", "lqg_pointing")
#: the column heads of the ratios (a reference the results do not have gets no column)
RATIO_HEADS = {"pi_kp1": "÷ PI", "lqg": "÷ LQG", "lqg_pointing": "÷ pointing LQG"}
#: how the numbers are computed (stored in the results file; the module doc says the same)
STATISTICS = (
    "agent: per training seed the mean 3-sigma over the test seeds; over the training seeds the "
    "interquartile mean with its 95 % percentile-bootstrap interval (resampling training seeds). "
    "reference: the mean over the test seeds with its 95 % percentile-bootstrap interval. "
    "agent / reference: two-level percentile bootstrap (test seeds resampled paired, training "
    "seeds resampled); reference / reference: paired percentile bootstrap over the test seeds; "
    "not significant when the interval contains 1. 2000 resamples, seeded generators. The same "
    "for the servo error (holds[h]) and the pointing error (holds[h]['pointing']); a pointing "
    "ratio divides by the reference's pointing error.")


#: the columns of the tracking, step and slew table: scenario -> ((column, head), ...); an
#: episode's value of each from its task's figures (:func:`column_values`)
SCENARIO_COLUMNS = {
    "track": (("servo_el", "track: el servo 3σ (mdeg)"), ("servo_az", "track: az servo 3σ (mdeg)")),
    "step": (("overshoot", "step: overshoot (%)"), ("settling", "step: 2 % settling (s)")),
    "slew": (("servo", "slew: servo 3σ (mdeg)"), ("terminated", "slew: terminated")),
}
#: salt offset of the scenario columns' resampling streams
_SCENARIO_SALT = 20


def column_values(scenario: str, column: str, figures: Mapping[str, Sequence[Any]]) -> np.ndarray:
    """Per test episode, one column of :data:`SCENARIO_COLUMNS` from a task's figures (the
    keys of :data:`dss14_env.agents.evaluation.FIGURES` and ``terminated``): the track's 3σ
    servo error per axis; the step's overshoot and 2 % settling time and the slew's 3σ servo
    error on the worse axis; the slew's terminations (1 per terminated episode).
    """
    def f(key: str) -> np.ndarray:
        return np.asarray([math.nan if v is None else float(v) for v in figures[key]], float)

    if column == "terminated":
        return np.asarray(figures["terminated"], float)
    if scenario == "track":
        return f(f"servo_three_sigma_mdeg_{column[-2:]}")
    key = {"overshoot": "overshoot_pct", "settling": "settling_time_s",
           "servo": "servo_three_sigma_mdeg"}[column]
    az, el = f(f"{key}_az"), f(f"{key}_el")
    return np.where(np.isnan(az), el, np.where(np.isnan(el), az, np.maximum(az, el)))


def column_summary(x: np.ndarray, column: str, rng: np.random.Generator) -> dict[str, Any]:
    """Statistics of one column: ``x`` ``(training seeds, test seeds)`` (an agent: IQM over
    training seeds of the mean over test seeds) or ``(test seeds,)`` (a reference: the mean
    with its interval over test seeds); terminations are counted (``count`` of ``episodes``);
    a column with non-finite values (a step that never settles: inf) has no statistic, only
    ``non_finite`` (how many) and ``infinite`` (how many of them are +inf).
    """
    x = np.asarray(x, float)
    d: dict[str, Any] = {"per_test_seed": x.tolist(), "episodes": int(x.size)}
    if column == "terminated":
        d["count"] = int(np.nansum(x))
        if x.ndim == 2:
            d["per_seed"] = [int(v) for v in np.nansum(x, axis=1)]
        return d
    bad = ~np.isfinite(x)
    if x.ndim == 2:
        d["per_seed"] = [float(v) for v in x.mean(axis=1)]
    if bad.any():
        d.update(non_finite=int(bad.sum()), infinite=int(np.isposinf(x).sum()))
    elif x.ndim == 2:
        d["iqm"] = iqm_ci(x.mean(axis=1), rng).as_dict()
    else:
        d["mean"] = bootstrap_ci(x, np.mean, rng).as_dict()
    return d


def _scenario_figures(summary: Mapping[str, Any], which: str,
                      scenario: str) -> list[Mapping[str, Any]] | None:
    """Every training seed's figures of one scenario, or None when a seed has none."""
    rows = []
    for e in summary["per_seed"]:
        res = e.get(which) or {}
        figs = res.get(scenario, {}).get("figures")
        if figs is None:
            return None
        rows.append(figs)
    return rows


def agent_scenarios(summary: Mapping[str, Any], which: str, salt: int) -> dict[str, Any]:
    """An agent's columns of the tracking, step and slew table: per scenario of
    :data:`SCENARIO_COLUMNS` its campaign scored (the ``figures`` of every seed), per column
    :func:`column_summary` over training x test seeds (and ``per_seed_final``).
    """
    out: dict[str, Any] = {}
    for i, (scen, cols) in enumerate(SCENARIO_COLUMNS.items()):
        best, final = _scenario_figures(summary, which, scen), _scenario_figures(summary, "final", scen)
        if best is None:
            continue
        out[scen] = {}
        for j, (col, _) in enumerate(cols):
            x = np.array([column_values(scen, col, f) for f in best])
            d = column_summary(x, col, _rng(salt, _SCENARIO_SALT, i, j))
            if final is not None:
                xf = np.array([column_values(scen, col, f) for f in final])
                d["per_seed_final"] = column_summary(xf, col, _rng(0)).get("per_seed")
            out[scen][col] = d
    return out


def reference_scenarios(figures: Mapping[str, Mapping[str, Sequence[Any]]], salt: int) -> dict[str, Any]:
    """A reference controller's columns: scenario -> its figures on the test seeds (as in a
    campaign's summary) -> per column :func:`column_summary` over the test seeds.
    """
    out: dict[str, Any] = {}
    for i, (scen, cols) in enumerate(SCENARIO_COLUMNS.items()):
        if scen in figures:
            out[scen] = {col: column_summary(column_values(scen, col, figures[scen]), col,
                                             _rng(salt, _SCENARIO_SALT, i, j))
                         for j, (col, _) in enumerate(cols)}
    return out


def _rng(*salt: int) -> np.random.Generator:
    return np.random.default_rng([BOOTSTRAP_SEED, *salt])


def agent_ratio(scores: np.ndarray, reference: np.ndarray, rng: np.random.Generator,
                n_resamples: int = N_RESAMPLES, level: float = 0.95) -> dict[str, Any]:
    """Ratio of an agent's IQM score to a reference's mean score, with its interval.

    :param scores: ``(training seeds, test seeds)`` 3σ of the agent
    :param reference: ``(test seeds,)`` 3σ of the reference on the same test seeds
    :param rng: source of the resampling
    :return: ``value``, ``ci95``, ``significant`` (the interval excludes 1), ``method``
    """
    x = np.asarray(scores, float)
    r = np.asarray(reference, float)
    if x.ndim != 2 or r.shape != (x.shape[1],) or not (np.isfinite(x).all() and np.isfinite(r).all()):
        raise ValueError(f"agent_ratio: need finite (seeds, tests) scores and (tests,) reference, "
                         f"got {x.shape} and {r.shape}")
    ns, nt = x.shape
    value = iqm(x.mean(axis=1)) / float(r.mean())
    out = np.empty(n_resamples)
    for b in range(n_resamples):
        j = rng.integers(0, nt, nt)
        k = rng.integers(0, ns, ns)
        out[b] = iqm(x[np.ix_(k, j)].mean(axis=1)) / float(r[j].mean())
    lo, hi = (float(v) for v in np.quantile(out, [(1 - level) / 2, (1 + level) / 2]))
    return {"value": float(value), "ci95": [lo, hi], "significant": not (lo <= 1.0 <= hi),
            "method": f"percentile bootstrap over training seeds and (paired) test seeds, "
                      f"{n_resamples} resamples"}


def _scores(summary: Mapping[str, Any], which: str, hold: str,
            key: str = "three_sigma_mdeg") -> np.ndarray:
    rows = []
    for e in summary["per_seed"]:
        res = e.get(which)
        if res is None or hold not in res or key not in res[hold]:
            raise ValueError(f"campaign {summary.get('config')}: seed index {e['seed_index']} has "
                             f"no {which} {key} of {hold}")
        rows.append(res[hold][key])
    return np.asarray(rows, float)


def has_pointing(summary: Mapping[str, Any], which: str = "best") -> bool:
    """Whether every seed of a campaign summary has test pointing scores of every hold."""
    return all(e.get(which) is not None and all(
        "pointing_three_sigma_mdeg" in e[which].get(h, {}) for h in HOLDS) for e in summary["per_seed"])


def _agent_hold(summary: Mapping[str, Any], which: str, hold: str, axis: str, key: str,
                references: Mapping[str, Mapping[str, Sequence[float]]], salt: tuple[int, ...]
                ) -> dict[str, Any]:
    """One hold's entry of an agent for one error (``key``): per-seed scores, IQM, ratios."""
    x = _scores(summary, which, hold, key)
    seeds_mean = x.mean(axis=1)
    d: dict[str, Any] = {
        "axis": axis,
        "per_seed": [float(v) for v in seeds_mean],
        "per_seed_final": [float(v) for v in _scores(summary, "final", hold, key).mean(axis=1)],
        "per_test_seed": x.tolist(),
        "iqm": iqm_ci(seeds_mean, _rng(*salt)).as_dict(),
        "ratios": {},
    }
    for i, ref in enumerate(RATIO_REFERENCES):
        if ref in references:
            d["ratios"][ref] = agent_ratio(x, np.asarray(references[ref][hold], float),
                                           _rng(*salt, i + 1))
    return d


def agent_entry(summary: Mapping[str, Any], references: Mapping[str, Mapping[str, Sequence[float]]],
                label: str, which: str = "best", salt: int = 0,
                extra: Mapping[str, Any] | None = None,
                pointing_references: Mapping[str, Mapping[str, Sequence[float]]] | None = None
                ) -> dict[str, Any]:
    """One agent's row: per-seed scores, IQM and interval, ratios to the references.

    :param summary: the campaign's ``summary.json``
    :param references: reference name -> hold -> 3σ per test seed (same seeds as the campaign)
    :param label: the name shown in tables
    :param which: ``"best"`` (the validation-selected policy, the protocol's) or ``"final"``
    :param salt: makes each agent's resampling stream its own (reproducible)
    :param extra: more keys to store (e.g. the recipe, the step of each selected policy)
    :param pointing_references: as ``references``, of the 3σ pointing error; with a summary
        that has pointing scores (:func:`has_pointing`) every hold gets a ``pointing`` entry
        of the same form as the servo error's
    """
    per_seed = summary["per_seed"]
    out: dict[str, Any] = {
        "label": label, "kind": "agent", "algo": summary["algo"], "env_id": summary["env_id"],
        "config": summary["config"], "scored_policy": which,
        "training_seeds": summary["training_seeds"],
        "test_seeds": summary["protocol"]["test_seeds"],
        "wall_s": [float(e["wall_s"]) for e in per_seed],
        "env_steps": [int(e["env_steps"]) for e in per_seed],
        "steps_per_s": [round(e["env_steps"] / e["wall_s"], 1) for e in per_seed],
        "holds": {},
    }
    pointing = has_pointing(summary, which) and has_pointing(summary, "final")
    for h, (hold, axis) in enumerate(HOLDS.items()):
        d = _agent_hold(summary, which, hold, axis, "three_sigma_mdeg", references, (salt, h))
        if pointing:
            d["pointing"] = _agent_hold(summary, which, hold, POINTING_AXES[hold],
                                        "pointing_three_sigma_mdeg", pointing_references or {},
                                        (salt, h, _POINTING_SALT))
        out["holds"][hold] = d
    scenarios = agent_scenarios(summary, which, salt)
    if scenarios:
        out["scenarios"] = scenarios
    out.update(dict(extra or {}))
    return out


def _reference_hold(v: np.ndarray, axis: str, references: Mapping[str, Mapping[str, Sequence[float]]],
                    hold: str, salt: tuple[int, ...]) -> dict[str, Any]:
    """One hold's entry of a reference for one error: mean with its interval, paired ratios."""
    d: dict[str, Any] = {"axis": axis, "per_test_seed": v.tolist(),
                         "mean": bootstrap_ci(v, np.mean, _rng(*salt)).as_dict(), "ratios": {}}
    for i, ref in enumerate(RATIO_REFERENCES):
        if ref in references:
            d["ratios"][ref] = ratio_ci(v, references[ref][hold], np.mean, _rng(*salt, i + 1),
                                        paired=True).as_dict()
    return d


def reference_entry(values: Mapping[str, Sequence[float]] | None,
                    references: Mapping[str, Mapping[str, Sequence[float]]], label: str,
                    salt: int = 0, extra: Mapping[str, Any] | None = None,
                    pointing: Mapping[str, Sequence[float]] | None = None,
                    pointing_references: Mapping[str, Mapping[str, Sequence[float]]] | None = None,
                    scenarios: Mapping[str, Mapping[str, Sequence[Any]]] | None = None
                    ) -> dict[str, Any]:
    """A reference controller's row: mean over the test seeds with its interval, ratios.

    :param values: hold -> 3σ servo error per test seed (None: not measured, the hold's servo
        entries stay empty)
    :param references: as in :func:`agent_entry`
    :param pointing: hold -> 3σ pointing error per test seed (None: no ``pointing`` entries)
    :param pointing_references: as ``references``, of the pointing error
    :param scenarios: scenario -> its figures per test seed (track, step, slew:
        :func:`reference_scenarios`; None: none)
    """
    out: dict[str, Any] = {"label": label, "kind": "reference", "holds": {}}
    for h, (hold, axis) in enumerate(HOLDS.items()):
        d: dict[str, Any] = {"axis": axis, "ratios": {}}
        if values is not None:
            d = _reference_hold(np.asarray(values[hold], float), axis, references, hold, (salt, h))
        if pointing is not None:
            d["pointing"] = _reference_hold(np.asarray(pointing[hold], float), POINTING_AXES[hold],
                                            pointing_references or {}, hold,
                                            (salt, h, _POINTING_SALT))
        out["holds"][hold] = d
    if scenarios:
        out["scenarios"] = reference_scenarios(scenarios, salt)
    out.update(dict(extra or {}))
    return out


def _analytic_hold(v: float, axis: str, references: Mapping[str, Mapping[str, Sequence[float]]],
                   hold: str, salt: tuple[int, ...]) -> dict[str, Any]:
    """One hold's entry of an exact value: the value, its ratios with the references' spread."""
    d: dict[str, Any] = {"axis": axis, "value": v, "ratios": {}}
    for i, ref in enumerate(RATIO_REFERENCES):
        if ref not in references:
            continue
        r = np.asarray(references[ref][hold], float)
        rng = _rng(*salt, i + 1)
        boot = np.array([v / r[rng.integers(0, r.size, r.size)].mean() for _ in range(N_RESAMPLES)])
        lo, hi = (float(q) for q in np.quantile(boot, [0.025, 0.975]))
        d["ratios"][ref] = {"value": v / float(r.mean()), "ci95": [lo, hi],
                            "significant": not (lo <= 1.0 <= hi),
                            "method": f"the exact value over the reference's mean, percentile "
                                      f"bootstrap over the test seeds, {N_RESAMPLES} resamples"}
    return d


def analytic_entry(values: Mapping[str, float] | None,
                   references: Mapping[str, Mapping[str, Sequence[float]]], label: str,
                   salt: int = 0, extra: Mapping[str, Any] | None = None,
                   pointing: Mapping[str, float] | None = None,
                   pointing_references: Mapping[str, Mapping[str, Sequence[float]]] | None = None
                   ) -> dict[str, Any]:
    """A row of exact expected values (no sampling: no interval of its own); its ratio to a
    reference has the interval of the reference's mean over the test seeds.

    :param values: hold -> the expected 3σ servo error (None: none, e.g. a pointing bound)
    :param pointing: hold -> the expected 3σ pointing error (None: none)
    :param pointing_references: as ``references``, of the pointing error
    """
    out: dict[str, Any] = {"label": label, "kind": "analytic", "holds": {}}
    for h, (hold, axis) in enumerate(HOLDS.items()):
        d: dict[str, Any] = {"axis": axis, "ratios": {}}
        if values is not None:
            d = _analytic_hold(float(values[hold]), axis, references, hold, (salt, h))
        if pointing is not None:
            d["pointing"] = _analytic_hold(float(pointing[hold]), POINTING_AXES[hold],
                                           pointing_references or {}, hold,
                                           (salt, h, _POINTING_SALT))
        out["holds"][hold] = d
    out.update(dict(extra or {}))
    return out


def _split(entry: tuple) -> tuple[str, Any, Any]:
    """``(label, values)`` or ``(label, values, pointing values)`` -> the three (pointing None)."""
    label, values, *rest = entry
    return label, values, (rest[0] if rest else None)


def build_results(agents: Mapping[str, tuple[str, Mapping[str, Any], Mapping[str, Any]]],
                  references: Mapping[str, tuple],
                  test_seeds: Sequence[int], meta: Mapping[str, Any] | None = None,
                  analytic: Mapping[str, tuple] | None = None,
                  scenario_references: Mapping[str, Mapping[str, Any]] | None = None) -> dict[str, Any]:
    """The results mapping (JSON-ready).

    :param agents: key -> ``(label, campaign summary, extra keys)``
    :param references: key -> ``(label, hold -> 3σ servo error per test seed)`` or ``(label,
        servo, hold -> 3σ pointing error per test seed)`` (servo None: not measured); must hold
        ``pi_kp1`` and ``lqg`` for the ratios
    :param test_seeds: the test seeds of the reference runs
    :param meta: stored as is (how the results were made)
    :param analytic: key -> ``(label, hold -> exact expected 3σ)`` or ``(label, servo, hold ->
        exact pointing 3σ)`` (either None: none) (rows after the references)
    :param scenario_references: reference key -> scenario -> its figures per test seed (the
        tracking, step and slew columns of the references; None: none)
    :raises ValueError: a campaign scored on other test seeds than the references
    """
    seeds = [int(s) for s in test_seeds]
    refs = {k: _split(v) for k, v in references.items()}
    ref_values = {k: v for k, (_, v, _) in refs.items() if v is not None}
    ref_pointing = {k: p for k, (_, _, p) in refs.items() if p is not None}
    rows: dict[str, Any] = {}
    for i, (key, (label, values, pointing)) in enumerate(refs.items()):
        rows[key] = reference_entry(values, ref_values, label, salt=100 + i, pointing=pointing,
                                    pointing_references=ref_pointing,
                                    scenarios=(scenario_references or {}).get(key))
    for i, (key, entry) in enumerate((analytic or {}).items()):
        label, values, pointing = _split(entry)
        rows[key] = analytic_entry(values, ref_values, label, salt=150 + i, pointing=pointing,
                                   pointing_references=ref_pointing)
    for i, (key, (label, summary, extra)) in enumerate(agents.items()):
        if [int(s) for s in summary["protocol"]["test_seeds"]] != seeds:
            raise ValueError(f"agent {key}: test seeds {summary['protocol']['test_seeds']} differ "
                             f"from the references' {seeds}")
        rows[key] = agent_entry(summary, ref_values, label, salt=200 + i, extra=extra,
                                pointing_references=ref_pointing)
    return {"meta": dict(meta or {}), "test_seeds": seeds, "holds": dict(HOLDS),
            "pointing_axes": dict(POINTING_AXES), "statistics": STATISTICS, "rows": rows}


# ------------------------------------------------------------------------------ Markdown
def _num(x: float) -> str:
    if not math.isfinite(x):
        return "–"
    return f"{x:.3g}" if abs(x) < 10 else f"{x:.1f}"


def _ci(d: Mapping[str, Any]) -> str:
    c = Cell.from_dict(d)
    return f"{_num(c.value)} [{_num(c.ci95[0])}, {_num(c.ci95[1])}]"


def _ratio(d: Mapping[str, Any] | None) -> str:
    if d is None:
        return "–"
    s = _ci(d)
    return s if RatioCell.from_dict(d).significant else f"{s} n.s."


def _error(row: Mapping[str, Any], hold: str, error: str) -> Mapping[str, Any] | None:
    """A row's entry of one hold for ``error`` (``servo`` or ``pointing``), None if not measured."""
    d = row["holds"][hold]
    d = d if error == "servo" else d.get("pointing")
    if d is None or not any(k in d for k in ("iqm", "mean", "value")):
        return None
    return d


def _score(row: Mapping[str, Any], hold: str, error: str = "servo") -> str:
    d = _error(row, hold, error)
    if d is None:
        return "–"
    if row["kind"] == "analytic":
        return f"{_num(d['value'])} (exact)"
    s = _ci(d["iqm"] if row["kind"] == "agent" else d["mean"])
    return f"**{s}**" if row["kind"] == "agent" else s


def _ratio_cell(row: Mapping[str, Any], key: str, hold: str, error: str, ref: str) -> str:
    d = _error(row, hold, error)
    if d is None:
        return "–"
    return "1" if key == ref else _ratio(d["ratios"].get(ref))


def _seeds_cell(row: Mapping[str, Any], n_test: int) -> str:
    if row["kind"] == "agent":
        return f"{len(row['training_seeds'])} × {n_test}"
    return f"{n_test}" if row["kind"] == "reference" else "–"


def _label(row: Mapping[str, Any]) -> str:
    """A row's label, marked † when the row is kept from earlier results (``kept_from``)."""
    return f"{row['label']} †" if row.get("kept_from") else row["label"]


def _error_table(results: Mapping[str, Any], error: str) -> str:
    """Markdown: every row's score of one error per hold with its interval and its ratios to
    the references of :data:`RATIO_REFERENCES` the results have ("–": not measured).
    """
    n_test = len(results["test_seeds"])
    axes = results["holds"] if error == "servo" else results.get("pointing_axes", POINTING_AXES)
    what = "servo" if error == "servo" else "pointing"
    refs = [r for r in RATIO_REFERENCES if r in results["rows"]]
    head = ["controller", "seeds"]
    for hold, axis in axes.items():
        head += [f"{hold.replace('hold_', '')} wind: {axis} {what} 3σ (mdeg)"]
        head += [RATIO_HEADS[r] for r in refs]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for key, row in results["rows"].items():
        cells = [_label(row), _seeds_cell(row, n_test)]
        for hold in axes:
            cells += [_score(row, hold, error)] + [_ratio_cell(row, key, hold, error, ref)
                                                   for ref in refs]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def summary_cell(d: Mapping[str, Any] | None, agent: bool) -> str:
    """A :func:`column_summary` as a table cell: the IQM or mean with its interval (an agent's
    in bold), the count of terminations, or why there is no statistic ("–": not measured).
    """
    if d is None:
        return "–"
    if "count" in d:
        return f"{d['count']} of {d['episodes']}"
    if "non_finite" in d:
        what = "never settles" if d["infinite"] == d["non_finite"] else "no value"
        return f"– ({what} in {d['non_finite']} of {d['episodes']})"
    s = _ci(d["iqm"] if "iqm" in d else d["mean"])
    return f"**{s}**" if agent else s


def _column_cell(row: Mapping[str, Any], scen: str, col: str) -> str:
    """One cell of the tracking, step and slew table ("–": not measured)."""
    return summary_cell(row.get("scenarios", {}).get(scen, {}).get(col), row["kind"] == "agent")


def has_scenarios(results: Mapping[str, Any]) -> bool:
    """Whether any row of the results has tracking, step or slew figures."""
    return any(row.get("scenarios") for row in results["rows"].values())


def scenario_table(results: Mapping[str, Any]) -> str:
    """Markdown: the rows' tracking, step and slew figures (:data:`SCENARIO_COLUMNS`; the
    rows that have any), with the statistics of the hold tables.
    """
    n_test = len(results["test_seeds"])
    head = ["controller", "seeds"] + [h for cols in SCENARIO_COLUMNS.values() for _, h in cols]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in results["rows"].values():
        if not row.get("scenarios"):
            continue
        cells = [_label(row), _seeds_cell(row, n_test)]
        cells += [_column_cell(row, scen, col) for scen, cols in SCENARIO_COLUMNS.items() for col, _ in cols]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main_table(results: Mapping[str, Any]) -> str:
    """Markdown: the pointing-error table, then the servo-error table (the same rows: every
    score per hold with its interval and its ratios to PI, LQG and pointing LQG), under a caption that says
    how they were computed.
    """
    n_test = len(results["test_seeds"])
    seeds = results["test_seeds"]
    caption = (
        f"The dish's true pointing error (first table: front wind elevation, side wind "
        f"cross-elevation) and the servo error at the drive encoders on the loaded axis (second "
        f"table: the report's Table 4 quantity), 3σ in mdeg, in the benchmark's holds (50 km/h, "
        f"60-s episodes, 5-s warm-up) on test seeds {seeds[0]}–{seeds[-1]}, never used in "
        f"training or selection. Learned agents (**bold**): interquartile mean over training "
        f"seeds of each seed's validation-selected policy (its mean over the {n_test} test "
        f"seeds), [95 % bootstrap interval over training seeds]; references: mean over the test "
        f"seeds [95 % bootstrap interval]. Ratios: two-level bootstrap over training and "
        f"(paired) test seeds; n.s.: the interval contains 1, not significant. Seeds column: "
        f"training × test seeds. –: not measured. Generated from "
        f"`docs/results/rl_results.json` (`scripts/rl_results.py`).")
    kept = sorted({r["kept_from"] for r in results["rows"].values() if r.get("kept_from")})
    if kept:
        caption += (f" †: a campaign whose trained runs are not in the repository: its row is the "
                    f"one computed on {', '.join(kept)} (the servo error only where its pointing "
                    f"columns show –; its ratios divide by the references of that time, on the same "
                    f"test seeds).")
    caption += "\n\n"
    out = (caption + "**Pointing error**\n\n" + _error_table(results, "pointing")
           + "\n**Servo error**\n\n" + _error_table(results, "servo"))
    if has_scenarios(results):
        out += ("\n**Tracking, step and slew** (the rows scored there, on the same test seeds: the "
                "benchmark's 40-s track in 30-70 km/h wind (3σ after the 5-s warm-up), 20-s 0.1° "
                "step (overshoot and 2 % settling time) and 50-s 5° slew (3σ) in their default "
                "bench lengths, each on the worse axis where both move; the statistics of the "
                "tables above, without ratios; terminated: episodes that hit the 1° error bound "
                "or the travel limits, of all test episodes)\n\n"
                + scenario_table(results))
    return out


def seeds_table(results: Mapping[str, Any]) -> str:
    """Markdown: the agents' per-training-seed scores (servo and pointing errors; "–": not
    measured), environment steps and wall time.
    """
    holds = list(results["holds"].items())
    paxes = results.get("pointing_axes", POINTING_AXES)
    head = ["agent", "training seed"]
    head += [f"{h.replace('hold_', '')} {paxes[h]} pointing 3σ (final)" for h, _ in holds]
    head += [f"{h.replace('hold_', '')} {a} servo 3σ (final)" for h, a in holds]
    head += ["selected at (steps)", "env steps", "wall (s)", "steps/s"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in results["rows"].values():
        if row["kind"] != "agent":
            continue
        for i, seed in enumerate(row["training_seeds"]):
            cells = [_label(row), str(seed)]
            for error in ("pointing", "servo"):
                for hold, _ in holds:
                    d = _error(row, hold, error)
                    cells.append("–" if d is None else
                                 f"{_num(d['per_seed'][i])} ({_num(d['per_seed_final'][i])})")
            sel = row.get("selected_at_steps")
            at = "–" if not sel else "final (none kept)" if sel[i] is None else str(sel[i])
            cells += [at, f"{row['env_steps'][i]:,}".replace(",", " "),
                      f"{row['wall_s'][i]:.0f}", f"{row['steps_per_s'][i]:.0f}"]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def rl_tables(results: Mapping[str, Any]) -> dict[str, str]:
    """The generated blocks: ``rl-table`` (scores and ratios), ``rl-seeds`` (per seed)."""
    return {"rl-table": main_table(results), "rl-seeds": seeds_table(results)}


__all__ = ["BOOTSTRAP_SEED", "HOLDS", "POINTING_AXES", "RATIO_HEADS", "RATIO_REFERENCES", "SCENARIO_COLUMNS",
           "STATISTICS", "agent_entry", "agent_ratio", "agent_scenarios", "analytic_entry",
           "build_results", "column_summary", "column_values", "has_pointing", "has_scenarios",
           "main_table", "reference_entry", "reference_scenarios", "rl_tables", "scenario_table",
           "seeds_table", "summary_cell"]
