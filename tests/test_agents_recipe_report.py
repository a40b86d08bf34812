"""The general recipe's many-seed report: ratios to the PI per seed and scenario, success rate,
IQM interval, performance profile and smoothness figures, on a hand-made campaign summary."""

from __future__ import annotations

import numpy as np
import pytest

from dss14_env.agents.recipe_report import PROFILE_TAUS, recipe_markdown, recipe_report

TASKS = [{"name": "hold_front", "pointing_axis": "el", "steps": 100},
         {"name": "track", "pointing_axis": None, "steps": 200}]


def _scores(front_el: list[float], track_el: list[float], track_xel: list[float], hits: int = 0) -> dict:
    n = len(front_el)
    return {"hold_front": {"figures": {"pointing_three_sigma_mdeg_el": front_el,
                                       "pointing_three_sigma_mdeg_xel": [0.1] * n,
                                       "accel_limit_hits": [hits] * n, "command_hf_share": [0.05] * n}},
            "track": {"figures": {"pointing_three_sigma_mdeg_el": track_el,
                                  "pointing_three_sigma_mdeg_xel": track_xel,
                                  "accel_limit_hits": [2 * hits] * n, "command_hf_share": [0.1, 0.3]}}}


def _summary() -> dict:
    pi = _scores([4.0, 6.0], [2.0, 2.0], [1.0, 3.0])  # track: worse axis 2, 3 -> mean 2.5
    seeds = [_scores([2.0, 3.0], [1.0, 1.0], [1.0, 1.5]),     # 0.5, 0.5 -> beats everywhere
             _scores([5.0, 5.0], [1.0, 1.0], [1.0, 1.0]),     # 1.0, 0.4: a tie does not beat
             _scores([3.0, 3.0], [3.0, 2.0], [0.0, 0.0], 4)]  # 0.6, 1.0
    return {"protocol": {"tasks": TASKS}, "references": {"test": {"pi_kp1": pi}},
            "per_seed": [{"seed_index": k, "training_seed": 10_000 + 1000 * k, "wall_s": 1.0, "env_steps": 64,
                          "run": f"seed_{k}", "best": s} for k, s in enumerate(seeds)]}


def test_ratios_success_rate_and_profile_follow_their_definitions() -> None:
    rep = recipe_report(_summary(), validation={0: -2.0, 1: -1.5, 2: -3.0})
    r = [row["scenarios"] for row in rep["per_seed"]]
    assert [x["hold_front"]["ratio_pi_kp1"] for x in r] == pytest.approx([0.5, 1.0, 0.6])
    assert [x["track"]["ratio_pi_kp1"] for x in r] == pytest.approx([0.5, 0.4, 1.0])
    assert [row["beats_pi_everywhere"] for row in rep["per_seed"]] == [True, False, False]
    assert rep["success_rate"] == {"share": pytest.approx(1 / 3), "seeds_beating_pi_everywhere": 1,
                                   "seeds": 3}
    prof = dict(zip(rep["profile"]["tau"], rep["profile"]["worst_scenario"], strict=True))
    assert prof[0.5] == pytest.approx(1 / 3) and prof[0.99] == pytest.approx(1 / 3) and prof[1.0] == 1.0
    assert np.all(np.diff(rep["profile"]["all_scenarios"]) >= 0) and len(PROFILE_TAUS) == len(prof)
    lo, hi = rep["iqm"]["hold_front"]["ratio_pi_kp1"]["ci95"]
    assert 0.5 <= lo <= rep["iqm"]["hold_front"]["ratio_pi_kp1"]["iqm"] <= hi <= 1.0
    assert r[2]["track"]["accel_hits"] == 8 and r[2]["hold_front"]["accel_hit_share"] == pytest.approx(0.04)
    assert r[0]["track"]["hf_share"] == pytest.approx(0.2)
    assert rep["shipped_seed_index"] == 1  # the best validation score, not the best test score
    md = recipe_markdown(rep)
    assert "**1 of 3**" in md and "| 10000 | 0.50 | 0.50 | 0.50 | yes |" in md


def test_a_summary_without_the_pi_is_refused() -> None:
    s = _summary()
    s["references"] = {}
    with pytest.raises(ValueError, match="no PI"):
        recipe_report(s)


def _with_step(summary: dict, settled: list[tuple[list[float], list[float]]],
               three_sigma: list[list[float]]) -> dict:
    """The summary with a step scenario: per controller (PI first, then the seeds) the settled
    rms el / xel per episode and the 3σ of the move (el = xel)."""
    summary["protocol"]["tasks"] = TASKS + [{"name": "step", "pointing_axis": None, "steps": 100}]
    entries = [summary["references"]["test"]["pi_kp1"]] + [e["best"] for e in summary["per_seed"]]
    for scores, (el, xel), ts in zip(entries, settled, three_sigma, strict=True):
        scores["step"] = {"figures": {"pointing_three_sigma_mdeg_el": ts,
                                      "pointing_three_sigma_mdeg_xel": ts,
                                      "pointing_settled_rms_mdeg_el": el,
                                      "pointing_settled_rms_mdeg_xel": xel,
                                      "accel_limit_hits": [0, 0], "command_hf_share": [0.0, 0.0]}}
    return summary


def test_moves_are_scored_by_the_worse_axis_rms_after_settling() -> None:
    """The headline success rate scores the step by the pointing rms after settling (worse axis),
    the earlier rule by its 3σ; an episode that never settles loses."""
    s = _with_step(_summary(),
                   [([0.5, 0.5], [0.3, 0.7]),        # PI: worse axis 0.5, 0.7 -> mean 0.6
                    ([0.3, 0.4], [0.2, 0.2]),        # seed 0: 0.3, 0.4 -> 0.35 / 0.6 < 1
                    ([0.1, 0.1], [0.1, 0.1]),        # seed 1: 0.1 (loses the hold anyway)
                    ([0.1, float("nan")], [0.1, 0.1])],  # seed 2: never settles -> inf
                   [[60.0, 60.0], [70.0, 70.0], [50.0, 50.0], [50.0, 50.0]])  # PI's 3σ lowest but two
    rep = recipe_report(s)
    step = [row["scenarios"]["step"] for row in rep["per_seed"]]
    assert [x["ratio_pi_kp1"] for x in step] == pytest.approx([70 / 60, 50 / 60, 50 / 60])
    assert step[0]["ratio_pi_kp1_settled"] == pytest.approx(0.35 / 0.6)
    assert step[1]["ratio_pi_kp1_settled"] == pytest.approx(0.1 / 0.6)
    assert step[2]["ratio_pi_kp1_settled"] == np.inf
    assert [r["beats_pi_everywhere_headline"] for r in rep["per_seed"]] == [True, False, False]
    assert [r["beats_pi_everywhere"] for r in rep["per_seed"]] == [False, False, False]
    assert rep["success_rate_headline"]["seeds_beating_pi_everywhere"] == 1
    assert rep["success_rate_headline"]["settled_scenarios"] == ["step"]
    assert rep["success_rate"]["seeds_beating_pi_everywhere"] == 0
    md = recipe_markdown(rep)
    assert "**1 of 3**" in md and "earlier rule" in md and "| 10000 | 0.58 | 0.58 | yes |" in md
