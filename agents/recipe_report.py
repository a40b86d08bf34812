"""A recipe's many-seed report: per training seed its validation-selected policy's pointing
error against the references in every test scenario, the success rate, the IQM over seeds with
its interval, a performance profile and the smoothness of the commands.

Input is a campaign's ``summary.json`` (:mod:`dss14_env.agents.campaign`: per training seed the
test figures of every episode of its ``eval/best`` policy, the references' on the same episodes)
and, optionally, more references scored on the same episodes (e.g. the pointing-aware LQG).

Definitions (every figure a mean over the test episodes of one scenario):

* **pointing figure** of an episode: a hold's 3σ pointing error on the axis its wind swings
  (front: el, side: xel); any other scenario's the larger of the two axes' 3σ (the worse axis);
* **settled figure** of an episode of a commanded move (the step and the slew: the scenarios
  whose episodes carry the move response): the dish's pointing rms after settling
  (:func:`dss14_env.baselines.rollout.move_response`, the bench's "Commanded move" tables) of
  the worse axis (el, xel); an episode that never settles counts as infinite.  The 3σ of a move
  measures the move itself, and it falls the faster the loop moves: overshoot lowers it (the
  PI's 30 % overshoot gives the lowest 3σ of the step), so a move is scored by how well the
  dish points once it has arrived;
* **ratio** of a seed to a reference: its mean pointing figure over the reference's, on the same
  episodes; a seed **beats** the reference in a scenario when the ratio is below 1;
* **success rate** (the headline): the share of seeds that beat the PI in every scenario,
  the holds and the track by the pointing figure, the commanded moves by the settled figure;
  beside it the earlier rule's, every scenario by its 3σ pointing figure
  (``success_rate_three_sigma``; ``success_rate`` of reports without moves' settled figures);
* **IQM** over seeds with its 95 % percentile-bootstrap interval over seeds
  (:func:`dss14_env.core.stats.iqm_ci`, :func:`scipy.stats.bootstrap`);
* **performance profile**: the share of seeds whose worst ratio over the scenarios is at most
  tau, over a grid of tau (at tau = 1 the success rate's complement of ties);
* **smoothness**: acceleration-limit hits per episode (the limiter's ``accel_limited`` steps) and
  their share of the episode's steps, and the share of the applied rate command's change lying
  above 5 Hz (:func:`dss14_env.core.smoothness.high_frequency_share`,
  both axes pooled).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from dss14_env.core.stats import iqm_ci

#: seed of every bootstrap here
BOOTSTRAP_SEED = 0
#: the performance profile's grid of tau (ratio to the PI)
PROFILE_TAUS = tuple(float(t) for t in np.round(np.arange(0.2, 2.001, 0.01), 2))


def pointing_figures(entry: Mapping[str, Any], pointing_axis: str | None) -> np.ndarray:
    """Each episode's pointing figure (module doc) from a scenario's ``task_scores`` entry."""
    f = entry["figures"]
    if pointing_axis is not None:
        return np.asarray(f[f"pointing_three_sigma_mdeg_{pointing_axis}"], float)
    return np.maximum(np.asarray(f["pointing_three_sigma_mdeg_el"], float),
                      np.asarray(f["pointing_three_sigma_mdeg_xel"], float))


#: the episode figures of the pointing rms after settling of a commanded move (el, xel)
SETTLED_KEYS = ("pointing_settled_rms_mdeg_el", "pointing_settled_rms_mdeg_xel")


def settled_figures(entry: Mapping[str, Any]) -> np.ndarray | None:
    """Each episode's settled figure (module doc) from a scenario's ``task_scores`` entry; None
    for a scenario without a commanded move (no settled figures).
    """
    f = entry["figures"]
    if not all(k in f for k in SETTLED_KEYS):
        return None
    worse = np.maximum(np.asarray(f[SETTLED_KEYS[0]], float), np.asarray(f[SETTLED_KEYS[1]], float))
    return np.where(np.isnan(worse), np.inf, worse)  # not settled: infinitely bad


def scenario_figures(entry: Mapping[str, Any], pointing_axis: str | None, steps: int) -> dict[str, float]:
    """A controller's figures in one scenario: mean pointing figure (mdeg), for a commanded move
    the mean settled figure (mdeg, ``settled_pointing_mdeg``), acceleration-limit hits per
    episode and per step, mean high-frequency share of the command change.
    """
    f = entry["figures"]
    hits = np.asarray(f["accel_limit_hits"], float)
    out = {"pointing_mdeg": float(np.mean(pointing_figures(entry, pointing_axis))),
           "accel_hits": float(np.mean(hits)), "accel_hit_share": float(np.mean(hits) / steps),
           "hf_share": float(np.nanmean(f["command_hf_share"]))}
    settled = settled_figures(entry)
    if settled is not None:
        out["settled_pointing_mdeg"] = float(np.mean(settled))
    return out


def headline_ratio(figs: Mapping[str, float], ref: str) -> float:
    """A scenario's headline ratio to ``ref``: the settled figure's for a commanded move, else
    the pointing figure's.
    """
    return figs.get(f"ratio_{ref}_settled", figs[f"ratio_{ref}"])


def controller_figures(scores: Mapping[str, Any], tasks: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """:func:`scenario_figures` of every task of a campaign's protocol (``summary["protocol"]["tasks"]``)."""
    return {t["name"]: scenario_figures(scores[t["name"]], t["pointing_axis"], int(t["steps"]))
            for t in tasks}


def _iqm(values: Sequence[float], rng: np.random.Generator) -> dict[str, Any]:
    """The IQM over seeds with its interval; None for both where a seed's ratio is infinite (a
    move that never settled), with the number of such seeds.
    """
    v = np.asarray(values, float)
    if not np.all(np.isfinite(v)):
        return {"iqm": None, "ci95": [None, None], "infinite_seeds": int(np.sum(~np.isfinite(v)))}
    est = iqm_ci(v, rng)
    return {"iqm": est.value, "ci95": [est.low, est.high]}


def recipe_report(summary: Mapping[str, Any], extra_refs: Mapping[str, Mapping[str, Any]] | None = None,
                  validation: Mapping[int, float] | None = None) -> dict[str, Any]:
    """The report (module doc) of a campaign's ``summary.json``.

    :param extra_refs: more references' ``task_scores`` on the campaign's test episodes, by name
    :param validation: seed index -> its selected evaluation's validation score (higher is
        better); the best names the seed to ship
    :raises ValueError: a summary without the PI's test scores or a seed without a selected policy
    """
    tasks = summary["protocol"]["tasks"]
    refs_scores = {**summary.get("references", {}).get("test", {}), **(extra_refs or {})}
    if "pi_kp1" not in refs_scores:
        raise ValueError("recipe_report: the summary has no PI (pi_kp1) test scores")
    refs = {name: controller_figures(s, tasks) for name, s in refs_scores.items()}
    names = [t["name"] for t in tasks]
    per_seed = []
    for e in summary["per_seed"]:
        if e.get("best") is None:
            raise ValueError(f"recipe_report: seed index {e['seed_index']} has no selected policy")
        figs = controller_figures(e["best"], tasks)
        for name in names:
            for ref, rf in refs.items():
                figs[name][f"ratio_{ref}"] = figs[name]["pointing_mdeg"] / rf[name]["pointing_mdeg"]
                if "settled_pointing_mdeg" in figs[name] and "settled_pointing_mdeg" in rf[name]:
                    figs[name][f"ratio_{ref}_settled"] = (figs[name]["settled_pointing_mdeg"]
                                                         / rf[name]["settled_pointing_mdeg"])
        worst = max(figs[n]["ratio_pi_kp1"] for n in names)
        worst_h = max(headline_ratio(figs[n], "pi_kp1") for n in names)
        row = {"seed_index": e["seed_index"], "training_seed": e["training_seed"], "wall_s": e["wall_s"],
               "env_steps": e["env_steps"], "scenarios": figs, "worst_ratio_pi": worst,
               "beats_pi_everywhere": bool(worst < 1.0), "worst_ratio_pi_headline": worst_h,
               "beats_pi_everywhere_headline": bool(worst_h < 1.0)}
        if validation is not None:
            row["validation_score"] = validation.get(e["seed_index"])
        per_seed.append(row)
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    iqm = {}
    for name in names:
        iqm[name] = {}
        for ref in refs:
            for key in (f"ratio_{ref}", f"ratio_{ref}_settled"):
                if all(key in r["scenarios"][name] for r in per_seed):
                    iqm[name][key] = _iqm([r["scenarios"][name][key] for r in per_seed], rng)
    worst = [r["worst_ratio_pi"] for r in per_seed]
    est = iqm_ci(worst, rng)

    n_ok = sum(r["beats_pi_everywhere"] for r in per_seed)
    n_ok_h = sum(r["beats_pi_everywhere_headline"] for r in per_seed)
    moves = [n for n in names if "ratio_pi_kp1_settled" in per_seed[0]["scenarios"][n]]
    out = {"scenarios": names, "references": refs, "per_seed": per_seed,
           "success_rate": {"share": n_ok / len(per_seed), "seeds_beating_pi_everywhere": n_ok,
                            "seeds": len(per_seed)},
           "success_rate_headline": {
               "rule": f"holds and track by the 3-sigma pointing figure; {', '.join(moves) or 'no move'} "
                       "by the pointing rms after settling (worse axis)",
               "settled_scenarios": moves, "share": n_ok_h / len(per_seed),
               "seeds_beating_pi_everywhere": n_ok_h, "seeds": len(per_seed)},
           "iqm": {**iqm, "worst_ratio_pi": {"iqm": est.value, "ci95": [est.low, est.high]},
                   "worst_ratio_pi_headline": _iqm([r["worst_ratio_pi_headline"] for r in per_seed], rng)},
           "profile": {"tau": list(PROFILE_TAUS),
                       "worst_scenario": [float(np.mean(np.asarray(worst) <= t)) for t in PROFILE_TAUS],
                       "worst_scenario_headline": [float(np.mean([r["worst_ratio_pi_headline"] <= t
                                                                  for r in per_seed])) for t in PROFILE_TAUS],
                       "all_scenarios": [float(np.mean([r["scenarios"][n]["ratio_pi_kp1"] <= t
                                                        for r in per_seed for n in names]))
                                         for t in PROFILE_TAUS]}}
    if validation:
        best = max((r for r in per_seed if r.get("validation_score") is not None),
                   key=lambda r: r["validation_score"])
        out["shipped_seed_index"] = best["seed_index"]
    return out




def _f(v: float, nd: int = 2) -> str:
    return "–" if v is None or not np.isfinite(v) else f"{v:.{nd}f}"


def _ci_cell(e: Mapping[str, Any]) -> str:
    return f"{_f(e['value'])} [{_f(e['low'])}, {_f(e['high'])}]"


def _iqm_cell(e: Mapping[str, Any]) -> str:
    return f"{_f(e['iqm'])} [{_f(e['ci95'][0])}, {_f(e['ci95'][1])}]"


def recipe_markdown(report: Mapping[str, Any]) -> str:
    """The report as Markdown tables: per seed the ratio to the PI per scenario (worst, beats
    the PI everywhere), the IQM row with its interval, the references' figures, the
    smoothness per seed and, when present, the direction/speed grid.
    """
    names = report["scenarios"]
    sr = report["success_rate"]
    lines = []
    hl = report.get("success_rate_headline")
    if hl is not None:
        lines += [f"Success rate (seeds whose validation-selected policy beats the PI's pointing in every "
                  f"scenario: {hl['rule']}): **{hl['seeds_beating_pi_everywhere']} of {hl['seeds']}** "
                  f"({100 * hl['share']:.0f} %). By the 3σ pointing error in every scenario (the "
                  f"earlier rule, which rewards a move's overshoot): {sr['seeds_beating_pi_everywhere']} "
                  f"of {sr['seeds']} ({100 * sr['share']:.0f} %).", ""]
        lines += ["Pointing rms after settling relative to the PI (worse axis, mean over the test "
                  "episodes; < 1 beats it):", "",
                  "| seed | " + " | ".join(hl["settled_scenarios"]) + " | worst (headline rule) | "
                  "beats PI everywhere (headline rule) |",
                  "|---|" + "---|" * (len(hl["settled_scenarios"]) + 2)]
        for r in report["per_seed"]:
            lines.append(f"| {r['training_seed']} | " + " | ".join(
                _f(r["scenarios"][n]["ratio_pi_kp1_settled"]) for n in hl["settled_scenarios"])
                + f" | {_f(r['worst_ratio_pi_headline'])} | "
                  f"{'yes' if r['beats_pi_everywhere_headline'] else 'no'} |")
        iq = report["iqm"]
        lines.append("| **IQM [95 % CI]** | " + " | ".join(
            _iqm_cell(iq[n]["ratio_pi_kp1_settled"]) for n in hl["settled_scenarios"])
            + f" | {_iqm_cell(iq['worst_ratio_pi_headline'])} | |")
        lines += ["", "The references' pointing rms after settling (worse axis, mdeg), "
                  + " / ".join(hl["settled_scenarios"]) + ": " + "; ".join(
                      f"{ref} " + " / ".join(_f(figs[n].get("settled_pointing_mdeg"), 3)
                                             for n in hl["settled_scenarios"])
                      for ref, figs in report["references"].items()) + ".", ""]
    else:
        lines += [f"Success rate (seeds whose validation-selected policy beats the PI's pointing error in "
                  f"every scenario): **{sr['seeds_beating_pi_everywhere']} of {sr['seeds']}** "
                  f"({100 * sr['share']:.0f} %).", ""]
    lines += [
             "3σ pointing error relative to the PI (mean over the test episodes; < 1 beats it):", "",
             "| seed | " + " | ".join(names) + " | worst | beats PI everywhere | validation score |",
             "|---|" + "---|" * (len(names) + 3)]
    for r in report["per_seed"]:
        cells = [_f(r["scenarios"][n]["ratio_pi_kp1"]) for n in names]
        val = r.get("validation_score")
        lines.append(f"| {r['training_seed']} | " + " | ".join(cells) + f" | {_f(r['worst_ratio_pi'])} | "
                     f"{'yes' if r['beats_pi_everywhere'] else 'no'} | {_f(val, 3)} |")
    iq = report["iqm"]
    lines.append("| **IQM [95 % CI]** | " + " | ".join(
        f"{_f(iq[n]['ratio_pi_kp1']['iqm'])} [{_f(iq[n]['ratio_pi_kp1']['ci95'][0])}, "
        f"{_f(iq[n]['ratio_pi_kp1']['ci95'][1])}]" for n in names)
        + f" | {_f(iq['worst_ratio_pi']['iqm'])} [{_f(iq['worst_ratio_pi']['ci95'][0])}, "
          f"{_f(iq['worst_ratio_pi']['ci95'][1])}] | | |")
    others = [k for k in iq[names[0]] if k != "ratio_pi_kp1"]
    for k in others:
        lines.append(f"| IQM {k.removeprefix('ratio_')} ratio | " + " | ".join(
            f"{_f(iq[n][k]['iqm'])} [{_f(iq[n][k]['ci95'][0])}, {_f(iq[n][k]['ci95'][1])}]"
            for n in names) + " | | | |")
    lines += ["", "References on the same test episodes (pointing figure, mdeg; acceleration-limit hits "
                  "per episode; high-frequency share of the command change):", "",
              "| controller | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for ref, figs in report["references"].items():
        lines.append(f"| {ref} | " + " | ".join(
            f"{_f(figs[n]['pointing_mdeg'])} mdeg; {figs[n]['accel_hits']:.0f} hits; "
            f"{100 * figs[n]['hf_share']:.1f} %" for n in names) + " |")
    lines += ["", "Smoothness per seed (acceleration-limit hits per episode / high-frequency share of the "
                  "command change):", "",
              "| seed | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for r in report["per_seed"]:
        lines.append(f"| {r['training_seed']} | " + " | ".join(
            f"{r['scenarios'][n]['accel_hits']:.0f} / {100 * r['scenarios'][n]['hf_share']:.1f} %"
            for n in names) + " |")
    if report.get("grid"):
        g = report["grid"]
        refs = [k.removeprefix("ratio_") for k in g["conditions"][0] if k.startswith("ratio_")]
        policy = f", policy: {g['policy']}" if g.get("policy") else ""
        lines += ["", f"Direction/speed grid ({g['what']}{policy}):", "",
                  "| wind | " + " | ".join(g["controllers"]) + " | "
                  + " | ".join(f"policy / {r} [95 % CI]" for r in refs) + " |",
                  "|---|" + "---|" * (len(g["controllers"]) + len(refs))]
        for c in g["conditions"]:
            lines.append(f"| {c['wind_speed_kmh']:g} km/h, {c['wind_direction_deg']:g}° | " + " | ".join(
                _f(c["pointing_mdeg"][k]) for k in g["controllers"]) + " | " + " | ".join(
                _ci_cell(c[f"ratio_{r}"]) for r in refs) + " |")
    return "\n".join(lines) + "\n"


__all__ = ["BOOTSTRAP_SEED", "PROFILE_TAUS", "SETTLED_KEYS", "controller_figures", "headline_ratio",
           "pointing_figures", "recipe_markdown", "recipe_report", "scenario_figures", "settled_figures"]
