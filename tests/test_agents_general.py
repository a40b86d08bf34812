"""The pieces of the general recipe: the feed-forward action map and its curve, symlog
observations, the mixture of scenarios in one VecEnv and the logarithmic training reward."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401
from dss14_env.agents.config import ConfigError, TrainConfig
from dss14_env.agents.envs import make_mixture_vec_env
from dss14_env.agents.interface import (
    InterfaceSpec,
    InterfaceWrapper,
    PolicyInterface,
    action_curve,
    symlog_observation,
    symlog_units,
)
from dss14_env.agents.vec_env import LogRewardVecEnv, make_sb3_vec_env
from dss14_env.envs.config import load_env_config
from dss14_env.envs.core import OBS

CFG = load_env_config()


# ------------------------------------------------------------------------------ action map
@pytest.mark.parametrize("b", [0.0, 1.0, 4.0, 8.0])
def test_action_curve_is_odd_monotone_and_reaches_the_full_scale(b: float) -> None:
    u = np.linspace(-1.0, 1.0, 201)
    g = action_curve(u, b)
    np.testing.assert_allclose(g, -g[::-1], atol=1e-15)
    assert np.all(np.diff(g) > 0)
    assert g[0] == pytest.approx(-1.0) and g[-1] == pytest.approx(1.0) and g[100] == 0.0
    h = 1e-6
    slope = (action_curve(np.array([h]), b)[0] - action_curve(np.array([-h]), b)[0]) / (2 * h)
    assert slope == pytest.approx(1.0 if b == 0 else b / math.sinh(b), rel=1e-6)


@pytest.mark.parametrize("gain, scale, curve", [(1.0, 1.0, 0.0), (1.35, 0.5, 4.0), (0.0, 0.2, 2.0)])
def test_feedforward_action_is_the_command_rate_plus_the_curved_output(gain: float, scale: float,
                                                                        curve: float) -> None:
    cfg = load_env_config(action_scale_deg_s=0.5)  # action units differ from rate-limit units
    spec = InterfaceSpec(action="feedforward", feedforward_gain=gain, residual_scale=scale,
                         action_curve=curve)
    itf = PolicyInterface(spec, cfg, 3)
    obs = np.zeros((3, 12), np.float32)
    obs[:, OBS.command_rate] = [[0.1, -0.2], [0.0, 0.0], [0.3, 0.05]]  # rate-limit units
    itf.observe(obs)
    u = np.array([[0.0, 0.0], [0.5, -0.25], [1.0, -1.0]])
    expected_ff = gain * obs[:, OBS.command_rate].astype(float) * 0.25 / 0.5  # to action units
    g = np.sinh(curve * u) / math.sinh(curve) if curve else u
    np.testing.assert_allclose(itf.action(u), np.clip(expected_ff + scale * g, -1, 1), rtol=1e-6)


def _slew_error(gain: float) -> float:
    """Largest |servo error| (mdeg) of a windless 1-deg slew with the policy output held at 0."""
    env = InterfaceWrapper(gym.make("DSS14-Slew-v0", wind_speed_kmh=0.0, slew_deg=1.0),
                           InterfaceSpec(action="feedforward", feedforward_gain=gain))
    env.reset(seed=0)
    worst = 0.0
    for _ in range(1000):  # 20 s: the move (7.7 s) and after
        _, _, term, trunc, info = env.step(np.zeros(2, np.float32))
        assert not term
        worst = max(worst, abs(info["servo_error_az_mdeg"]), abs(info["servo_error_el_mdeg"]))
    return worst


def test_feedforward_gain_of_the_inverse_dc_gain_follows_a_slew_closely() -> None:
    """Consequence: with gain 1 the rate loop's DC gain (about 0.74) leaves a quarter of the
    move behind; with 1.35 the feed-forward alone follows within a few percent of it."""
    lagging, matched = _slew_error(1.0), _slew_error(1.35)
    assert lagging > 150.0          # mdeg of a 1000-mdeg move
    assert matched < 0.25 * lagging


# ------------------------------------------------------------------------------ symlog
def test_symlog_observation_in_mdeg() -> None:
    units = symlog_units(CFG)
    obs = np.zeros((1, 12), np.float32)
    obs[0, OBS.error] = [0.1, -10.0]               # 1 mdeg, -100 mdeg at error_scale 10
    obs[0, OBS.prev_rate] = [0.004, 0.0]           # 0.001 deg/s = 1 mdeg/s
    out = symlog_observation(obs, units)[0]
    np.testing.assert_allclose(out[OBS.error], [math.log(2.0), -math.log(101.0)], rtol=1e-6)
    np.testing.assert_allclose(out[OBS.prev_rate], [math.log(2.0), 0.0], rtol=1e-5)


def test_symlog_policy_observations_stay_in_their_space_and_peek_equals_observe() -> None:
    spec = InterfaceSpec(obs_symlog=True, history=3, obs_entries=(0, 1, 2, 3, 6, 7, 10, 11))
    env = InterfaceWrapper(gym.make("DSS14-Step-v0"), spec)
    obs, _ = env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(120):
        assert env.observation_space.contains(obs)
        obs, *_ = env.step(rng.uniform(-0.3, 0.3, 2).astype(np.float32))
    assert np.all(np.isfinite(obs))
    itf2 = PolicyInterface(spec, CFG, 2)
    o = np.zeros((2, 12), np.float32)
    o[:, OBS.error] = [[3.0, -2.0], [0.01, 0.5]]
    peeked = itf2.peek(o[[1]], np.array([1]))
    np.testing.assert_array_equal(peeked[0], itf2.observe(o)[1])


# ------------------------------------------------------------------------------ mixture
MIX = [{"preset": "hold", "n_envs": 2, "env_kwargs": {}, "max_episode_steps": None},
       {"preset": "step", "n_envs": 1, "env_kwargs": {}, "max_episode_steps": 40},
       {"preset": "track", "n_envs": 2, "env_kwargs": {"wind_speed_kmh": 30.0}, "max_episode_steps": None}]


def test_mixture_rows_are_their_presets_seeded_in_sequence() -> None:
    mix = make_mixture_vec_env(MIX, {"max_episode_steps": 60}, 10_000, CFG)
    assert mix.num_envs == 5
    assert mix.get_attr("scenario_name") == ["hold", "hold", "step", "track", "track"]
    parts = [make_sb3_vec_env("DSS14-Hold-v0", 2, seed=10_000, max_episode_steps=60),
             make_sb3_vec_env("DSS14-Step-v0", 1, seed=10_002, max_episode_steps=40),
             make_sb3_vec_env("DSS14-v0", 2, seed=10_003, max_episode_steps=60, wind_speed_kmh=30.0)]
    obs = mix.reset()
    np.testing.assert_array_equal(obs, np.concatenate([p.reset() for p in parts]))
    rng = np.random.default_rng(1)
    for k in range(70):  # through the step's end (40) and the others' (60)
        a = rng.uniform(-0.1, 0.1, (5, 2)).astype(np.float32)
        o, r, d, infos = mix.step(a)
        sep = [p.step(a[s]) for p, s in zip(parts, (slice(0, 2), slice(2, 3), slice(3, 5)), strict=True)]
        np.testing.assert_array_equal(o, np.concatenate([x[0] for x in sep]))
        np.testing.assert_array_equal(r, np.concatenate([x[1] for x in sep]))
        np.testing.assert_array_equal(d, np.concatenate([x[2] for x in sep]))
        if k == 39:
            assert d.tolist() == [False, False, True, False, False]


@pytest.mark.parametrize("mixture, match", [
    ([{"preset": "nope", "n_envs": 4}], "'preset' must be one of"),
    ([{"preset": "hold", "n_envs": 3}], "must sum to n_envs = 4"),
    ([{"preset": "hold", "n_envs": 4, "speed": 3}], r"mixture\[0\]': must be a mapping"),
    ([{"preset": "hold", "n_envs": 0}, {"preset": "step", "n_envs": 4}], "'n_envs' must be an integer"),
    ([{"preset": "hold", "n_envs": 4, "max_episode_steps": 2.5}], "'max_episode_steps'"),
    ("hold", "must be a list of parts"),
])
def test_bad_mixtures_are_named_in_one_line(mixture: object, match: str) -> None:
    with pytest.raises(ConfigError, match=match) as err:
        TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "n_envs": 4, "mixture": mixture}, "cfg.yaml")
    assert "\n" not in str(err.value) and "field 'mixture" in str(err.value)


def test_a_mixture_part_of_another_action_scale_is_refused() -> None:
    mix = [{"preset": "hold", "n_envs": 1, "env_kwargs": {"action_scale_deg_s": 0.02},
            "max_episode_steps": None}]
    with pytest.raises(ValueError, match="action_scale_deg_s is 0.02 in hold"):
        make_mixture_vec_env(mix, {}, 10_000, CFG)


# ------------------------------------------------------------------------------ log reward
def test_log_reward_is_the_log_of_the_cost_from_the_servo_errors() -> None:
    venv = make_sb3_vec_env("DSS14-Step-v0", 2, seed=10_000, max_episode_steps=200,
                            info_keys=("servo_error_az_mdeg", "servo_error_el_mdeg"))
    wrapped = LogRewardVecEnv(venv, 0.01, CFG, 0.99)
    wrapped.reset()
    a = np.zeros((2, 2), np.float32)
    for _ in range(100):
        _, r, _, infos = wrapped.step(a)
        e = np.array([[i["servo_error_az_mdeg"], i["servo_error_el_mdeg"]] for i in infos])
        cost = (e ** 2).sum(axis=1) / CFG.error_scale_mdeg ** 2  # no action change: a held at 0
        np.testing.assert_allclose(r, -np.log1p(cost / 0.01), rtol=2e-6, atol=1e-6)


def test_log_reward_never_pays_for_terminating() -> None:
    """The terminal penalty exceeds the discounted sum of the worst per-step value before it."""
    venv = make_sb3_vec_env("DSS14-Slew-v0", 1, seed=10_000, max_episode_steps=3000)
    wrapped = LogRewardVecEnv(venv, 0.01, CFG, 0.99)
    err_units = CFG.max_error_deg * 1e3 / CFG.error_scale_mdeg
    worst = math.log1p((2 * err_units ** 2 + 8 * CFG.action_change_weight) / 0.01)
    assert wrapped.terminal == pytest.approx(worst / 0.01)
    wrapped.reset()
    for k in range(3000):  # full reverse rate: the error passes 1 deg and the episode terminates
        _, r, d, infos = wrapped.step(np.array([[-1.0, -1.0]], np.float32) * np.sign(k + 1))
        if d[0]:
            assert not infos[0]["TimeLimit.truncated"]
            assert r[0] <= -wrapped.terminal
            break
    else:
        pytest.fail("the slew never terminated")


# ------------------------------------------------------------------------------ history filters
def test_history_filters_are_first_order_low_passes_from_the_first_observation() -> None:
    spec = InterfaceSpec(obs_entries=(0,), history_entries=(0, 11), history_filters=(0.1, 1.0))
    itf = PolicyInterface(spec, CFG, 2)
    assert itf.obs_dim == 1 + 2 * 2
    o = np.zeros((2, 12), np.float32)
    o[:, 0] = [1.0, -2.0]
    first = itf.observe(o)
    np.testing.assert_allclose(first[:, 1:].reshape(2, 2, 2)[:, :, 0], [[1.0, 1.0], [-2.0, -2.0]])
    o[:, 0] = [3.0, 0.0]  # a step of +2 in both rows: 1 - exp(-k dt / tau) of it after k steps
    for _ in range(25):
        out = itf.observe(o)
    for j, tau in enumerate((0.1, 1.0)):
        frac = -math.expm1(-25 * CFG.dt / tau)
        np.testing.assert_allclose(out[:, 1 + 2 * j], [1.0 + 2.0 * frac, -2.0 + 2.0 * frac], rtol=1e-5)


def test_history_filters_peek_equals_observe_and_restart_refills() -> None:
    spec = InterfaceSpec(history=2, history_filters=(0.05, 0.5), obs_symlog=True)
    itf = PolicyInterface(spec, CFG, 3)
    rng = np.random.default_rng(2)
    for _ in range(10):
        itf.observe(rng.normal(0, 1, (3, 12)).astype(np.float32))
    o = rng.normal(0, 1, (3, 12)).astype(np.float32)
    peeked = itf.peek(o[[0, 2]], np.array([0, 2]))
    np.testing.assert_array_equal(peeked, itf.observe(o)[[0, 2]])
    itf.restart(np.array([False, True, False]))
    o2 = rng.normal(0, 1, (3, 12)).astype(np.float32)
    again = itf.observe(o2)
    fresh = PolicyInterface(spec, CFG, 1).observe(o2[[1]])
    np.testing.assert_array_equal(again[1], fresh[0])


@pytest.mark.parametrize("taus", [(0.0,), (-1.0,), (61.0,), "0.5", (0.1,) * 9, (True,)])
def test_bad_history_filters_are_refused(taus: object) -> None:
    with pytest.raises(ValueError, match="history_filters must be"):
        InterfaceSpec(history_filters=taus)


# ------------------------------------------------------------------------------ context
def test_context_marks_axis_encoders_in_every_face() -> None:
    spec = InterfaceSpec(history=1, obs_symlog=True, context=("axis_encoders",))
    drive = InterfaceWrapper(gym.make("DSS14-Hold-v0"), spec)
    axis = InterfaceWrapper(gym.make("DSS14-Hold-v0", encoders="axis"), spec)
    for env, flag in ((drive, 0.0), (axis, 1.0)):
        obs, _ = env.reset(seed=3)
        assert obs.shape == env.observation_space.shape and obs[-1] == flag
        assert env.observation_space.contains(obs)
        obs, *_ = env.step(np.zeros(2, np.float32))
        assert obs[-1] == flag
    # a mixture: each row's own part, in the VecEnv and in its terminal observations
    from dss14_env.agents.vec_env import InterfaceVecEnv
    mix = [{"preset": "hold", "n_envs": 2, "env_kwargs": {"encoders": "axis"}, "max_episode_steps": 5},
           {"preset": "track", "n_envs": 1, "env_kwargs": {}, "max_episode_steps": 5}]
    venv = InterfaceVecEnv(make_mixture_vec_env(mix, {}, 7, CFG), spec, CFG)
    assert venv.reset()[:, -1].tolist() == [1.0, 1.0, 0.0]
    for _ in range(5):
        obs, _, dones, infos = venv.step(np.zeros((3, 2), np.float32))
    assert dones.all() and [i["terminal_observation"][-1] for i in infos] == [1.0, 1.0, 0.0]
    assert obs[:, -1].tolist() == [1.0, 1.0, 0.0]


def test_scored_policy_sees_the_context_of_the_environment_it_acts_on(tmp_path) -> None:
    """A policy with ``context`` scored on an axis-encoder hold sees 1 there, 0 on the
    environment it was trained on (the drives), whatever the batch size."""
    import torch
    from stable_baselines3 import PPO

    from dss14_env.agents.config import TrainConfig as TC
    from dss14_env.agents.envs import resolve_env
    from dss14_env.agents.policy import PolicyController

    cfg = TC.from_dict({"env_id": "DSS14-Plain-v0", "n_envs": 1, "env_kwargs": {
        "base_id": "DSS14-Hold-v0", "context": ["axis_encoders"]}}, "cfg.yaml")
    plan = resolve_env(cfg)
    env = InterfaceWrapper(gym.make("DSS14-Hold-v0"), plan.interface)
    model = PPO("MlpPolicy", env, n_steps=8, batch_size=8, device="cpu")
    torch.set_num_threads(1)
    ctrl = PolicyController(model.policy, cfg, None, "p", env=gym.make("DSS14-Hold-v0", encoders="axis"))
    for n in (1, 3):
        ctrl.reset_batch(n)
        assert ctrl.interface.context.tolist() == [[1.0]] * n
    ctrl.target_env(gym.make("DSS14-Hold-v0"))
    assert ctrl.interface.context.tolist() == [[0.0]] * 3


@pytest.mark.parametrize("ctx", [("nope",), "axis_encoders", ("axis_encoders", "axis_encoders")])
def test_bad_context_is_refused(ctx: object) -> None:
    with pytest.raises(ValueError, match="context must be distinct names of"):
        InterfaceSpec(context=ctx)


# ------------------------------------------------------------------------------ general selection
def test_general_selection_scores_every_scenario_and_disqualifies() -> None:
    from dss14_env.agents.evaluation import dss14_tasks
    from dss14_env.agents.train import general_figure, selection_score

    tasks = {t.name: t for t in dss14_tasks(scenarios=("hold_side", "track", "step"))}
    res = {"hold_side": {"three_sigma_mdeg": np.array([2.0, 2.0])},
           "track": {"servo_three_sigma_mdeg_az": np.array([1.0, 4.0]),
                     "servo_three_sigma_mdeg_el": np.array([4.0, 1.0])},
           "step": {"settling_time_s_az": np.array([5.0, 6.0]), "settling_time_s_el": np.array([7.0, 2.0])}}
    figs = {n: general_figure(tasks[n], r) for n, r in res.items()}
    np.testing.assert_allclose(figs["track"], [4.0, 4.0])  # the worse axis
    np.testing.assert_allclose(figs["step"], [7.0, 6.0])
    cfg = TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "select_by": "general",
                                 "eval_scenarios": ["hold_side", "track", "step"]})
    assert selection_score(cfg, np.zeros(6), figs) == pytest.approx(-(2.0 * 4.0 * 6.5) ** (1 / 3))
    assert selection_score(cfg, np.zeros(6), figs, terminated=True) == -np.inf
    figs["step"] = np.array([np.inf, 6.0])  # a step that never settles
    assert selection_score(cfg, np.zeros(6), figs) == -np.inf


def test_beating_the_reference_needs_every_task_below_it() -> None:
    from dss14_env.agents.train import beats_reference

    ref = {"hold_side": 2.0, "step": 9.9}
    assert beats_reference({"hold_side": np.array([1.0, 2.5]), "step": np.array([6.0])}, ref)
    assert not beats_reference({"hold_side": np.array([1.0, 3.5]), "step": np.array([6.0])}, ref)
    assert not beats_reference({"hold_side": np.array([1.0]), "step": np.array([np.inf, 1.0])}, ref)
    assert not beats_reference({"hold_side": np.array([2.0]), "step": np.array([1.0])}, ref)  # a tie


def test_reference_figures_are_the_references_validation_scores() -> None:
    """The PI's figures that a selection with ``select_reference`` compares against equal the
    PI's validation scores computed by the campaign's reference lines (another path), and the
    step's is its settling time (the PI settles the 0.1 deg step in 8-12 s: docs/bench.md)."""
    from dss14_env.agents.campaign_report import validation_references
    from dss14_env.agents.train import reference_figures, validation_tasks

    cfg = TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "select_by": "general",
                                 "select_reference": "pi_kp1", "eval_seeds": [1000, 1001],
                                 "eval_episode_steps": 600, "eval_scenarios": ["hold_side_axis", "step"]})
    tasks = validation_tasks(cfg)
    ref = reference_figures(cfg, tasks)
    other = validation_references(tasks, [1000, 1001], 600)["pi_kp1"]
    assert ref["hold_side_axis"] == pytest.approx(other["hold_side_axis"]["three_sigma"], rel=1e-9)
    assert 8.0 < ref["step"] < 12.0


def test_select_reference_needs_figures() -> None:
    with pytest.raises(ConfigError, match="field 'select_reference': needs select_by") as err:
        TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "select_reference": "pi_kp1"})
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match="field 'select_reference'"):
        TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "select_by": "general", "select_reference": "mpc"})


def test_an_untrained_policy_keeps_a_best_that_does_not_beat_the_pi(tmp_path) -> None:
    """Selection against the PI: an untrained policy never beats it on every task, so each
    evaluation is recorded as not qualified, and ``eval/best`` is still kept (best score)."""
    from dss14_env.agents.train import train

    cfg = dict(env_id="DSS14-Plain-v0", env_kwargs={"base_id": "DSS14-v0", "max_episode_steps": 100},
               n_envs=2, total_timesteps=400, n_steps=100, batch_size=100, n_epochs=1, net_arch=[8],
               eval_freq=200, eval_seeds=[1000], eval_episode_steps=300, checkpoint_freq=0,
               select_by="general", select_reference="pi_kp1", eval_scenarios=["hold_side", "hold_front"],
               test_scenarios=["hold_side"], progress_bar=False, verbose=0)
    run = train(cfg, run_dir=tmp_path / "run")
    with np.load(run / "eval/evaluations.npz") as d:
        assert d["selection_qualified"].tolist() == [False, False]
    assert (run / "eval/best/policy.pt").is_file()


def test_validation_tasks_follow_eval_scenarios() -> None:
    from dss14_env.agents.train import validation_tasks

    cfg = TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "eval_scenarios": ["step", "hold_side_axis"]})
    tasks = validation_tasks(cfg)
    assert [t.name for t in tasks] == ["step", "hold_side_axis"]
    assert tasks[1].axis == "az" and tasks[1].env_kwargs.get("encoders") == "axis"
    with pytest.raises(ConfigError, match="field 'eval_scenarios'"):
        TrainConfig.from_dict({"env_id": "DSS14-Plain-v0", "eval_scenarios": ["step", "step"]})


# ------------------------------------------------------------------------------ smooth commands
def test_action_change_penalty_charges_each_change_of_the_environments_action() -> None:
    """w ||a[k] - a[k-1]||^2 of the actions the environment receives comes off the reward,
    nothing on an episode's first step (reset and after a done row)."""
    from dss14_env.agents.vec_env import ActionChangePenaltyVecEnv

    plain = make_sb3_vec_env("DSS14-Step-v0", 2, seed=10_000, max_episode_steps=3)
    pen = ActionChangePenaltyVecEnv(make_sb3_vec_env("DSS14-Step-v0", 2, seed=10_000, max_episode_steps=3),
                                    200.0)
    plain.reset()
    pen.reset()
    acts = [np.array([[0.1, 0.0], [0.0, 0.0]]), np.array([[0.3, 0.0], [0.0, -0.2]]),
            np.array([[0.3, 0.1], [0.0, -0.2]]), np.array([[0.0, 0.0], [0.5, 0.0]])]
    want_pen = [[0.0, 0.0], [200 * 0.04, 200 * 0.04], [200 * 0.01, 0.0], [0.0, 0.0]]  # 3rd step ends
    for a, w in zip(acts, want_pen, strict=True):
        _, r0, d0, _ = plain.step(a.astype(np.float32))
        _, r1, d1, _ = pen.step(a.astype(np.float32))
        np.testing.assert_array_equal(d0, d1)
        np.testing.assert_allclose(r0 - r1, w, rtol=1e-5, atol=1e-5)
    with pytest.raises(ValueError, match="action-change penalty weight"):
        ActionChangePenaltyVecEnv(plain, -1.0)


def test_action_filter_low_passes_the_action_and_restarts_with_the_episode() -> None:
    """action_filter_s: a first-order low-pass of the action map's output; an episode's first
    action passes unfiltered; the filter is part of the saved interface."""
    spec = InterfaceSpec(action_filter_s=0.05)
    assert spec.to_dict()["action_filter_s"] == 0.05
    it = PolicyInterface(spec, CFG, 2)
    alpha = 1.0 - math.exp(-CFG.dt / 0.05)
    it.observe(np.zeros((2, 12), np.float32))
    np.testing.assert_allclose(it.action(np.array([[0.5, -0.5], [0.2, 0.0]])), [[0.5, -0.5], [0.2, 0.0]],
                               rtol=1e-6)
    got = it.action(np.array([[1.0, -0.5], [0.2, 0.0]]))
    np.testing.assert_allclose(got[0], [0.5 + alpha * 0.5, -0.5], rtol=1e-6)
    it.restart(np.array([False, True]))
    got = it.action(np.array([[1.0, -0.5], [-0.4, 0.0]]))
    assert got[1, 0] == pytest.approx(-0.4)  # the restarted row starts afresh
    assert got[0, 0] == pytest.approx(0.5 + alpha * 0.5 + alpha * (0.5 - alpha * 0.5), rel=1e-6)
    none = PolicyInterface(InterfaceSpec(), CFG, 1)
    none.observe(np.zeros((1, 12), np.float32))
    none.action(np.array([[0.5, 0.0]]))
    assert none.action(np.array([[1.0, 0.0]]))[0, 0] == 1.0
    with pytest.raises(ValueError, match="action_filter_s"):
        InterfaceSpec(action_filter_s=-0.1)


def test_action_change_penalty_needs_the_batched_vec_env() -> None:
    from dss14_env.agents.envs import make_train_vec_env, resolve_env

    cfg = TrainConfig.from_dict({"algo": "ppo", "env_id": "DSS14-Plain-v0", "vec_env": "dummy",
                                 "action_change_penalty": 10.0, "n_envs": 1}, "cfg.yaml")
    with pytest.raises(ValueError, match="cfg.yaml: key 'action_change_penalty': needs the batched"):
        make_train_vec_env(cfg, resolve_env(cfg), CFG, None)


# ------------------------------------------------------------------------------ base per encoder placement
def _lqg_pointing_run(encoders: str, seed: int, steps: int) -> tuple[np.ndarray, np.ndarray, object]:
    """The observations a pointing-aware LQG sees in a hold with ``encoders``, its commands and
    the hold's configuration."""
    from dss14_env.baselines.lqg import PointingLQGController

    env = gym.make("DSS14-Hold-v0", encoders=encoders, wind_direction="side")
    ctrl = PointingLQGController(env)
    ctrl.reset_batch(1)
    obs, _ = env.reset(seed=seed)
    seen, acts = [], []
    for _ in range(steps):
        a = ctrl.act_batch(obs[None])[0]
        seen.append(obs)
        acts.append(a)
        obs, *_ = env.step(a)
    env.close()
    return np.asarray(seen, np.float32), np.asarray(acts), env.unwrapped.config


def test_lqg_base_is_designed_for_each_rows_encoders() -> None:
    """An interface built on a drive-encoder configuration, its rows set to act on axis-, drive-
    and axis-encoder holds: at zero policy output each row commands what the pointing-aware LQG
    designed for that row's hold commands (the bench's ``lqg_pointing``), step by step."""
    runs = [_lqg_pointing_run(e, s, 120) for e, s in (("axis", 3), ("drive", 4), ("axis", 5))]
    spec = InterfaceSpec(base="lqg_pointing", action="residual", residual_scale=0.01,
                         lqg_features=("command", "disturbance"), context=("axis_encoders",))
    iface = PolicyInterface(spec, CFG, 3)
    iface.set_context([r[2] for r in runs])
    got = []
    for k in range(120):
        iface.observe(np.stack([r[0][k] for r in runs]))
        got.append(iface.action(np.zeros((3, 2))))
    want = np.stack([r[1] for r in runs], 1)
    assert np.abs(want[:, [0, 2]] - want[:, [1]]).max() > 1e-4  # the placements command differently
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-5, atol=1e-7)
    assert iface.context[:, 0].tolist() == [1.0, 0.0, 1.0]


def test_training_vec_env_designs_the_base_for_its_sub_environments_encoders() -> None:
    """The training VecEnv's interface, built on a drive-encoder configuration over a mixture of
    axis-encoder holds (no context feature asked), commands at zero policy output what the
    pointing-aware LQG designed for those holds commands."""
    from dss14_env.agents.vec_env import InterfaceVecEnv
    from dss14_env.baselines.lqg import PointingLQGController

    spec = InterfaceSpec(base="lqg_pointing", action="residual", residual_scale=0.01,
                         lqg_features=("command", "disturbance"))
    mix = [{"preset": "hold", "n_envs": 2, "env_kwargs": {"encoders": "axis"}, "max_episode_steps": 200}]
    inner = make_mixture_vec_env(mix, {}, 3, CFG)
    venv = InterfaceVecEnv(inner, spec, CFG)
    ref = PointingLQGController(inner.get_attr("config")[0])
    ref.reset_batch(2)
    obs = inner.reset()
    for _ in range(100):
        venv.interface.observe(obs)
        a = venv.interface.action(np.zeros((2, 2)))
        np.testing.assert_allclose(a, ref.act_batch(obs), rtol=1e-5, atol=1e-7)
        obs, *_ = inner.step(a)
