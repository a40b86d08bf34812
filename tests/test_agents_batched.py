"""The trained-policy controller's batched API (agents/policy.py): row i of ``act_batch`` is
``act`` on the same observation sequence, for plain, residual, model-informed and recurrent
policies, with rows restarted independently."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401
from dss14_env.agents.algos import build_policy
from dss14_env.agents.config import TrainConfig
from dss14_env.agents.envs import resolve_env
from dss14_env.agents.interface import PolicyInterface
from dss14_env.agents.policy import PolicyController, load_policy
from dss14_env.agents.storage import NormStats


def _controller(cfg: dict, seed: int = 0) -> PolicyController:
    """A controller over a freshly initialised (untrained) network of the config's architecture
    and made-up normalisation statistics: what is tested is the composition, not the skill."""
    import torch

    c = TrainConfig.from_dict(cfg)
    plan = resolve_env(c)
    env_cfg = gym.make(plan.base_id).unwrapped.config
    dim = PolicyInterface(plan.interface, env_cfg, 1).obs_dim if plan.interface else 12
    torch.manual_seed(seed)
    policy = build_policy(c, dim, [-1.0, -1.0], [1.0, 1.0])
    with torch.no_grad():  # a visible output: larger last-layer weights
        for p in policy.parameters():
            p.mul_(3.0)
    rng = np.random.default_rng(seed)
    stats = NormStats(rng.normal(0, 0.1, dim), rng.uniform(0.5, 2.0, dim), 100.0, 10.0, 1e-8)
    return PolicyController(policy, c, stats, "test")


def _sequences(n: int, steps: int, seed: int) -> np.ndarray:
    """Observation sequences of n hold episodes driven by the PI (plausible observations)."""
    from dss14_env.baselines.pi import PIController

    out = np.zeros((steps, n, 12), np.float32)
    for i in range(n):
        env = gym.make("DSS14-Hold-v0", wind_direction="side" if i % 2 else "front")
        pi = PIController(env)
        obs, _ = env.reset(seed=seed + i)
        for k in range(steps):
            out[k, i] = obs
            obs, *_ = env.step(pi.act(obs))
    return out


CASES = {
    "plain": {"env_id": "DSS14-Hold-v0"},
    "plain_history": {"env_id": "DSS14-Hold-v0", "frame_stack": 4},
    "residual_pi": {"env_id": "DSS14-Residual-v0", "env_kwargs": {"history": 3}},
    "residual_lqg": {"env_id": "DSS14-ResidualLQG-v0"},
    "kalman_obs": {"env_id": "DSS14-KalmanObs-v0"},
    "plain_small_scale": {"env_id": "DSS14-Hold-v0", "env_kwargs": {"action_scale_deg_s": 0.05}},
    "recurrent": {"algo": "recurrent_ppo", "env_id": "DSS14-Residual-v0", "net_arch": [16],
                  "lstm_hidden_size": 8},
    "sac": {"algo": "sac", "env_id": "DSS14-Hold-v0", "net_arch": [16, 16]},
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_act_batch_rows_equal_act_on_the_same_sequences(case: str) -> None:
    n, steps, restart_at = 3, 40, 25
    seq = _sequences(n, steps, seed=20)
    batch = _controller(CASES[case])
    singles = [_controller(CASES[case]) for _ in range(n)]
    batch.reset_batch(n)
    for s in singles:
        s.reset()
    assert type(batch).batchable is True
    for k in range(steps):
        if k == restart_at:  # row 1's sub-environment was reset: only it starts over
            mask = np.array([False, True, False])
            batch.restart(mask)
            singles[1].reset()
        a = batch.act_batch(seq[k])
        assert a.shape == (n, 2) and a.dtype == np.float32 and np.all(np.abs(a) <= 1.0)
        assert batch.info_batch["inference_time_s"].shape == (n,)
        for i in range(n):
            np.testing.assert_allclose(a[i], singles[i].act(seq[k, i]), rtol=1e-6, atol=1e-7)
    assert not np.allclose(a[0], a[2])  # different rows, different actions


def test_restart_changes_the_restarted_row_only() -> None:
    seq = _sequences(2, 20, seed=30)
    a = _controller(CASES["residual_pi"])
    b = _controller(CASES["residual_pi"])
    a.reset_batch(2)
    b.reset_batch(2)
    for k in range(15):
        a.act_batch(seq[k])
        b.act_batch(seq[k])
    b.restart(np.array([True, False]))
    ra, rb = a.act_batch(seq[15]), b.act_batch(seq[15])
    assert np.array_equal(ra[1], rb[1]) and not np.array_equal(ra[0], rb[0])


def test_batched_inputs_are_checked() -> None:
    ctrl = _controller(CASES["plain"])
    ctrl.reset_batch(2)
    with pytest.raises(ValueError, match="observation shape"):
        ctrl.act_batch(np.zeros((3, 12)))
    bad = np.zeros((2, 12))
    bad[1, 4] = np.inf
    with pytest.raises(ValueError, match=r"non-finite observation in row\(s\) \[1\]"):
        ctrl.act_batch(bad)
    with pytest.raises(ValueError, match="mask"):
        ctrl.restart(np.ones(3, bool))
    with pytest.raises(ValueError, match="n must be"):
        ctrl.reset_batch(0)


def test_the_shipped_policy_batched_equals_single() -> None:
    seq = _sequences(4, 30, seed=40)
    batch = load_policy()
    single = load_policy()
    batch.reset_batch(4)
    out = np.stack([batch.act_batch(seq[k]) for k in range(30)])
    for i in range(4):
        single.reset()
        ref = np.stack([single.act(seq[k, i]) for k in range(30)])
        np.testing.assert_allclose(out[:, i], ref, rtol=1e-6, atol=1e-7)  # float32 BLAS order


def test_actions_are_converted_to_the_scoring_envs_action_scale() -> None:
    ctrl = _controller(CASES["plain_small_scale"])  # trained at 0.05 deg/s per unit action
    seq = _sequences(1, 5, seed=50)[:, 0]
    ctrl.reset()
    a_train = np.array([ctrl.act(o) for o in seq])
    ctrl.target_env(gym.make("DSS14-Hold-v0"))  # scored at the default 0.25 deg/s
    ctrl.reset()
    a_score = np.array([ctrl.act(o) for o in seq])
    np.testing.assert_allclose(a_score, np.clip(a_train * 0.05 / 0.25, -1, 1), rtol=1e-6, atol=1e-8)
