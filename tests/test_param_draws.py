"""Counted parameter draws (model/uncertainty.py draw_params): the environments' reset info and
the campaign's results record the draws rejected before each plant, by reason."""

from __future__ import annotations

import numpy as np
import pytest

from dss14_env.bench import campaign
from dss14_env.bench.campaign_report import draw_summary, draws_markdown
from dss14_env.bench.campaign_spec import CampaignSpec
from dss14_env.envs.env import DSS14Env
from dss14_env.model.assembly import default_model
from dss14_env.model.uncertainty import (
    REJECT_REASONS,
    SWEEP_PARAMS,
    draw_params,
    draw_stable_params,
    perturbed_rate_loop,
    rejection_reason,
)


def _first_rejecting_seed(limit: int = 400) -> int:
    for s in range(limit):
        if draw_params(np.random.default_rng(s)).n_rejected:
            return s
    raise AssertionError(f"no seed below {limit} rejects a draw")


def test_counts_are_the_rejected_draws_replayed() -> None:
    """Replaying the generator: every counted draw fails the test for the reason counted."""
    seed = _first_rejecting_seed()
    d = draw_params(np.random.default_rng(seed))
    assert set(d.rejected) == set(REJECT_REASONS) and d.n_rejected >= 1
    m = default_model()
    rng = np.random.default_rng(seed)
    seen = dict.fromkeys(REJECT_REASONS, 0)
    for _ in range(d.n_rejected + 1):
        vals = {}
        for name in SWEEP_PARAMS:
            lo, hi = m.cfg.params[name].range
            vals[name] = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
        why = rejection_reason(perturbed_rate_loop(m, vals), *m.gains("kp1"))
        if why:
            seen[why] += 1
    assert seen == d.rejected
    assert why is None and vals == d.values
    assert draw_stable_params(np.random.default_rng(seed)) == d.values  # the same plants as before


def test_unconditioned_draws_keep_the_plants_the_pi_rejects() -> None:
    seed = _first_rejecting_seed()
    d = draw_params(np.random.default_rng(seed), condition_on_pi=False)
    assert d.rejected["pi_loop_unstable"] == d.rejected["pi_loop_within_margin"] == 0
    assert d.values != draw_params(np.random.default_rng(seed)).values


def test_reset_info_records_rejected_draws() -> None:
    seed = _first_rejecting_seed()
    env = DSS14Env(randomize_params=True)
    info = env.reset(seed=seed)[1]
    # the env's generator is not default_rng(seed), so only the form is fixed here
    assert set(info["params_rejected"]) == set(REJECT_REASONS)
    assert all(isinstance(v, int) and v >= 0 for v in info["params_rejected"].values())
    assert DSS14Env().reset(seed=0)[1]["params_rejected"] == {}
    counts = [sum(env.reset(seed=s)[1]["params_rejected"].values()) for s in range(150)]
    assert sum(counts) > 0  # about 2 % of draws are rejected: 150 resets see some


def test_campaign_plants_record_their_draws_and_default_fingerprint_is_kept() -> None:
    rec = campaign.plant_record(3)
    assert rec["params"] == campaign.plant_params(3) == dict(sorted(
        draw_stable_params(np.random.default_rng((3, 0))).items()))
    assert set(rec["params_rejected"]) == set(REJECT_REASONS)
    assert set(rec["pi_loop_abscissa"]) == set(default_model().cfg.gain_sets)
    spec = CampaignSpec(controllers=("pi_kp1",), plants=2)
    assert "condition_on_pi" not in spec.as_dict()
    un = CampaignSpec(controllers=("pi_kp1",), plants=2, condition_on_pi=False)
    assert un.as_dict()["condition_on_pi"] is False and un.fingerprint() != spec.fingerprint()
    assert CampaignSpec.from_dict(un.as_dict()) == un


def test_draw_summary_counts_shares() -> None:
    spec = CampaignSpec(controllers=("pi_kp1", "lqg"), plants=2, condition_on_pi=False)
    plants = [{"index": 0, "params_rejected": {"pi_loop_unstable": 0}, "pi_loop_abscissa": {"kp1": 0.02}},
              {"index": 1, "params_rejected": {"pi_loop_unstable": 0}, "pi_loop_abscissa": {"kp1": -0.3}}]
    eps = [{"plant": k, "controller": c, "terminated": (k == 0 and c == "pi_kp1")}
           for k in (0, 1) for c in ("pi_kp1", "lqg")]
    d = draw_summary(spec, plants, eps)
    assert d["terminated_share"]["pi_kp1"]["k"] == 1 and d["terminated_share"]["lqg"]["k"] == 0
    assert d["pi_unstable_share"]["kp1"]["k"] == 1
    assert d["rejected_share"]["k"] == 0 and not d["condition_on_pi"]
    assert "not conditioned" in draws_markdown(d)


def test_condition_on_pi_must_be_a_bool() -> None:
    with pytest.raises(ValueError, match="condition_on_pi"):
        CampaignSpec(controllers=("pi_kp1",), plants=1, condition_on_pi="no")
