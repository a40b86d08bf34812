"""The training recipes as configurations: the interface keys they need (``obs_entries``,
``lqg_features``, the ``DSS14-Plain-v0`` id), the validation score that selects ``eval/best``
(``select_by``), the shipped recipe files and their rl-zoo3 entries, and the campaign's scoring
against the benchmark's runner."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

import dss14_env  # noqa: F401
from dss14_env.agents.config import TrainConfig, load_config
from dss14_env.agents.envs import check_env
from dss14_env.agents.evaluation import DSS14_TASKS, FINAL_SCORING, run_task
from dss14_env.agents.hyperparams import hyperparams_path, load_hyperparams
from dss14_env.agents.interface import (
    LQG_FEATURE_WIDTHS,
    NO_ABSOLUTE_ANGLES,
    InterfaceSpec,
    PolicyInterface,
)
from dss14_env.agents.policy import PolicyController, load_policy
from dss14_env.agents.train import selection_key, selection_score, train
from dss14_env.baselines.lqg import LQGController, PointingLQGController
from dss14_env.bench.runner import run

HOLD_SIDE = {"wind_direction": "side", "wind_speed_kmh": 50.0}


def _hold_observations(steps: int, seed: int, direction: str = "side") -> np.ndarray:
    """Observations of a hold driven by the LQG (plausible inputs for the interface)."""
    env = gym.make("DSS14-Hold-v0", wind_direction=direction)
    lqg = LQGController(env)
    obs, _ = env.reset(seed=seed)
    out = []
    for _ in range(steps):
        out.append(obs)
        obs, *_ = env.step(lqg.act(obs))
    return np.asarray(out, np.float32)


# ------------------------------------------------------------------------------ observation entries
@pytest.mark.parametrize("entries", [NO_ABSOLUTE_ANGLES, (0, 1, 10, 11), (11, 0), None])
def test_obs_entries_are_the_chosen_environment_entries(entries: tuple | None) -> None:
    env = gym.make("DSS14-Plain-v0", history=2, obs_entries=entries, **HOLD_SIDE)
    n = 12 if entries is None else len(entries)
    assert env.observation_space.shape == (n + 2 * 4,)
    raw_env = gym.make("DSS14-Hold-v0", **HOLD_SIDE)
    obs, _ = env.reset(seed=3)
    raw, _ = raw_env.reset(seed=3)
    rng = np.random.default_rng(0)
    raws = [raw]
    for _ in range(30):
        a = rng.uniform(-0.2, 0.2, 2).astype(np.float32)
        obs, *_ = env.step(a)
        raw, *_ = raw_env.step(a)
        raws.append(raw)
    idx = list(range(12)) if entries is None else list(entries)
    np.testing.assert_array_equal(obs[:n], raw[idx])
    # history: entries 0, 1, 10, 11 of the two previous steps, newest first
    np.testing.assert_array_equal(obs[n:], np.concatenate([raws[-2][[0, 1, 10, 11]],
                                                           raws[-3][[0, 1, 10, 11]]]))
    assert env.observation_space.contains(obs)


def test_the_plain_id_drops_the_absolute_angles_and_keeps_eight_steps() -> None:
    env = gym.make("DSS14-Plain-v0")
    assert env.observation_space.shape == (8 + 8 * 4,)
    assert NO_ABSOLUTE_ANGLES == (0, 1, 2, 3, 6, 7, 10, 11)
    obs, _ = env.reset(seed=0)
    a = np.array([0.5, -0.5], np.float32)
    _, _, _, _, info_w = env.step(a)
    raw_env = gym.make("DSS14-Hold-v0")
    raw_env.reset(seed=0)
    _, _, _, _, info_r = raw_env.step(a)  # absolute action: the policy output is the env action
    assert info_w["servo_error_az_mdeg"] == info_r["servo_error_az_mdeg"]


# ------------------------------------------------------------------------------ LQG features
FULL = InterfaceSpec(base="lqg", action="residual", residual_scale=0.02)
SLICES = {"command": slice(0, 2), "disturbance": slice(2, 4), "output": slice(4, 6),
          "law": slice(6, 12)}


@pytest.mark.parametrize("features", [("command", "disturbance"), ("law",), ("output", "command"),
                                      tuple(LQG_FEATURE_WIDTHS)])
def test_lqg_features_are_the_named_parts_of_the_full_estimate(features: tuple) -> None:
    cfg = gym.make("DSS14-Hold-v0").unwrapped.config
    full = PolicyInterface(FULL, cfg, 2)
    sub = PolicyInterface(InterfaceSpec(base="lqg", action="residual", residual_scale=0.02,
                                        lqg_features=features, obs_entries=NO_ABSOLUTE_ANGLES),
                          cfg, 2)
    assert sub.n_features == sum(LQG_FEATURE_WIDTHS[f] for f in features)
    seqs = np.stack([_hold_observations(120, 5, "side"), _hold_observations(120, 6, "front")], 1)
    for obs in seqs:
        f, s = full.observe(obs), sub.observe(obs)
        want = np.concatenate([f[:, 12:][:, SLICES[name]] for name in features], axis=1)
        np.testing.assert_array_equal(s[:, 8:], want)
        np.testing.assert_array_equal(s[:, :8], obs[:, list(NO_ABSOLUTE_ANGLES)])
        np.testing.assert_array_equal(sub.action(np.zeros((2, 2))), full.action(np.zeros((2, 2))))
    assert np.abs(want).max() > 0  # the features move: a real comparison


@pytest.mark.parametrize("name, controller", [("ppo_residual_lqg", LQGController),
                                              ("ppo_residual_lqg_pointing", PointingLQGController)])
def test_the_lqg_residual_recipe_at_zero_output_is_the_lqg(name: str, controller: type) -> None:
    """At zero policy output the residual recipe's loop is its base controller's (the LQG, or
    the pointing-aware LQG): the same servo and pointing errors step by step."""
    cfg = load_config(name)
    kw = {k: v for k, v in cfg.env_kwargs.items() if k != "max_episode_steps"}
    wrapped = gym.make(cfg.env_id, **{**kw, "wind_direction": "side"})
    base = gym.make("DSS14-Hold-v0", wind_direction="side")
    lqg = controller(base)
    wrapped.reset(seed=7)
    obs, _ = base.reset(seed=7)
    e_w, e_b = [], []
    for _ in range(300):
        *_, info_w = wrapped.step(np.zeros(2, np.float32))
        obs, *_, info_b = base.step(lqg.act(obs))
        e_w.append([info_w["servo_error_az_mdeg"], info_w["pointing_error_xel_mdeg"]])
        e_b.append([info_b["servo_error_az_mdeg"], info_b["pointing_error_xel_mdeg"]])
    assert np.abs(e_b).max(axis=0).min() > 0.05
    np.testing.assert_array_equal(e_w, e_b)


@pytest.mark.parametrize("key, value, match", [
    ("obs_entries", [0, 12], "obs_entries must be distinct observation indices 0-11"),
    ("obs_entries", [1, 1], "obs_entries must be distinct"),
    ("obs_entries", [], "obs_entries must be distinct"),
    ("obs_entries", "0,1", "obs_entries must be distinct"),
    ("lqg_features", ["command", "kalman"], "lqg_features must be distinct names of"),
    ("lqg_features", "command", "lqg_features must be distinct names of"),
    ("estimate", "yes", "estimate must be true or false"),
])
def test_bad_interface_keys_are_named(key: str, value: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make("DSS14-ResidualLQG-v0", **{key: value})
    cfg = TrainConfig.from_dict({"env_id": "DSS14-ResidualLQG-v0", "env_kwargs": {key: value}},
                                source="x.yaml")
    with pytest.raises(ValueError, match=f"x.yaml: key 'env_kwargs': {match}"):
        check_env(cfg)


# ------------------------------------------------------------------------------ the shipped recipes
RECIPES = {  # config -> (algo, policy observation size, action scale the policy was trained at)
    "ppo_plain": ("ppo", 8 + 8 * 4, 0.02),
    "ppo_plain_sweep": ("ppo", 8 + 8 * 4, 0.02),  # the plain recipe's environment at every point
    "ppo_residual_lqg": ("ppo", 8 + 4 + 4 * 4, 0.25),
    "ppo_plain_pointing": ("ppo", 8 + 8 * 4, 0.02),
    "ppo_residual_lqg_pointing": ("ppo", 8 + 4 + 4 * 4, 0.25),
    "ppo_residual_pi": ("ppo", 12 + 2 + 8 * 4, 0.25),
    "ppo_residual_pi_hold": ("ppo", 12 + 2 + 8 * 4, 0.25),
    "recurrent_ppo": ("recurrent_ppo", 4, 0.02),
    "sac": ("sac", 8 + 8 * 4, 0.02),
    "ppo_general": ("ppo", 8 + (8 + 3) * 4, 0.25),  # 8 steps and 3 filters of 4 entries
    "ppo_general_random": ("ppo", 8 + (8 + 3) * 4, 0.25),
    "ppo_general_lqg": ("ppo", 8 + 4 + 4 * 4, 0.25),  # general, on the beam: residual on lqg_pointing
    "ppo_general_lqg2": ("ppo", 8 + 4 + 4 * 4 + 1, 0.25),  # the same + where the encoders sit
    "ppo_general_lqg3": ("ppo", 8 + 4 + 4 * 4 + 1, 0.25),  # the same on the scheduled base
    "ppo_general_lqg4": ("ppo", 8 + 4 + 4 * 4 + 2, 0.25),  # + the episode's wind reading
}


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_recipe_configs_build_their_environment(name: str) -> None:
    algo, obs_dim, scale = RECIPES[name]
    cfg = load_config(name)
    # a recipe on the beam is rewarded, validated and selected on the pointing error; a general
    # recipe is selected over every bench scenario
    on_beam = name.endswith("_pointing") or name.startswith("ppo_general_lqg")
    select = "pointing" if on_beam else "general" if "general" in name else "three_sigma"
    assert cfg.algo == algo and cfg.select_by == select
    assert cfg.seed >= 10_000 and all(1000 <= s < 10_000 for s in cfg.eval_seeds)
    plan, obs_space, act_space, env_cfg = check_env(cfg)
    assert env_cfg.reward == ("pointing" if on_beam else "servo")
    assert cfg.eval_env_kwargs.get("reward", "servo") == env_cfg.reward
    assert obs_space.shape == (obs_dim,) and act_space.shape == (2,)
    assert env_cfg.action_scale_deg_s == scale
    # the reward's action-change term keeps the benchmark's weight in deg/s: w = (scale/0.25)^2
    assert env_cfg.action_change_weight == pytest.approx((scale / 0.25) ** 2)


#: the rl-zoo3 entries that carry a recipe: (algo, hyperparameter file, env id) -> config
ZOO_RECIPES = {("ppo", "ppo", "DSS14-Plain-v0"): "ppo_plain",
               ("ppo", "ppo", "DSS14-ResidualLQG-v0"): "ppo_residual_lqg",
               ("ppo", "ppo", "DSS14-Residual-v0"): "ppo_residual_pi",
               ("recurrent_ppo", "recurrent_ppo", "DSS14-Plain-v0"): "recurrent_ppo",
               ("sac", "sac", "DSS14-Plain-v0"): "sac",
               ("ppo", "ppo_pointing", "DSS14-Plain-v0"): "ppo_plain_pointing",
               ("ppo", "ppo_pointing", "DSS14-ResidualLQG-v0"): "ppo_residual_lqg_pointing",
               ("ppo", "ppo_general", "DSS14-Plain-v0"): "ppo_general"}
#: keys a recipe's zoo entry must give as the training config does
RECIPE_KEYS = ("env_id", "env_kwargs", "n_envs", "total_timesteps", "normalize_obs",
               "normalize_reward", "learning_rate", "gamma", "net_arch", "activation_fn",
               "log_std_init", "n_steps", "batch_size", "n_epochs", "gae_lambda", "clip_range",
               "ent_coef", "max_grad_norm", "lstm_hidden_size", "enable_critic_lstm",
               "buffer_size", "learning_starts", "tau", "train_freq", "gradient_steps")


@pytest.mark.parametrize("algo, file, env_id", sorted(ZOO_RECIPES))
def test_zoo_entries_are_the_recipes(algo: str, file: str, env_id: str) -> None:
    zoo = load_hyperparams(algo, env_id, hyperparams_path(file)).to_dict()
    cfg = load_config(ZOO_RECIPES[(algo, file, env_id)]).to_dict()
    for key in RECIPE_KEYS:
        if key in cfg:
            assert zoo[key] == cfg[key], key


def test_zoo_entries_are_plain_yaml_for_rl_zoo3() -> None:
    """rl-zoo3 passes every key but its own to the algorithm: none of this package's keys."""
    ours = {"frame_stack", "select_by", "eval_seeds", "eval_episode_steps", "obs_entries"}
    for file in ("ppo", "recurrent_ppo", "sac", "ppo_pointing", "ppo_general"):
        for env_id, entry in yaml.safe_load(hyperparams_path(file).read_text()).items():
            assert not ours & set(entry), (file, env_id)


# ------------------------------------------------------------------------------ selection score
def _cfg(select_by: str) -> TrainConfig:
    return TrainConfig.from_dict({"env_id": "DSS14-Hold-v0", "select_by": select_by})


def test_selection_score_by_return_and_by_three_sigma() -> None:
    r = np.array([-3.0, -5.0])
    assert selection_score(_cfg("return"), r) == -4.0
    sig = {"hold_front": np.array([1.0, 3.0]), "hold_side": np.array([8.0, 8.0])}
    assert selection_score(_cfg("three_sigma"), r, sig) == pytest.approx(-np.sqrt(2.0 * 8.0))
    assert selection_score(_cfg("three_sigma"), r, sig, terminated=True) == -np.inf
    assert selection_score(_cfg("three_sigma"), r, {"a": np.array([np.nan])}) == -np.inf
    with pytest.raises(ValueError, match="select_by"):
        TrainConfig.from_dict({"select_by": "median"})


finite = st.floats(0.01, 100.0, allow_nan=False)


@settings(max_examples=50, deadline=None)
@given(st.lists(finite, min_size=1, max_size=6), st.lists(finite, min_size=1, max_size=6),
       st.floats(0.1, 10.0))
def test_three_sigma_score_scales_and_orders(front: list, side: list, c: float) -> None:
    cfg = _cfg("three_sigma")
    r = np.zeros(2)
    sig = {"f": np.array(front), "s": np.array(side)}
    s = selection_score(cfg, r, sig)
    assert s < 0
    assert selection_score(cfg, r, {k: c * v for k, v in sig.items()}) == pytest.approx(c * s)
    worse = {"f": sig["f"] * 1.5, "s": sig["s"]}  # a larger error in one hold scores lower
    assert selection_score(cfg, r, worse) < s


@pytest.mark.parametrize("select_by", ["three_sigma", "pointing"])
def test_training_keeps_the_best_validation_three_sigma(tmp_path: Path, select_by: str) -> None:
    """eval/best is the evaluation with the lowest geometric mean of the holds' validation 3σ
    of the selected error (servo, or pointing), and that policy scores that 3σ again."""
    cfg = {"algo": "ppo", "env_id": "DSS14-Plain-v0",
           "env_kwargs": {"max_episode_steps": 100, "action_scale_deg_s": 0.02, "history": 2},
           "n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 1, "net_arch": [8],
           "total_timesteps": 384, "eval_freq": 128, "eval_seeds": [1000],
           "eval_episode_steps": 300, "select_by": select_by, "checkpoint_freq": 0,
           "progress_bar": False, "verbose": 0}
    key = selection_key(TrainConfig.from_dict(cfg))
    assert key == ("pointing_three_sigma_mdeg" if select_by == "pointing" else "three_sigma_mdeg")
    run_dir = train(cfg, run_dir=tmp_path / "run")
    with np.load(run_dir / "eval" / "evaluations.npz") as d:
        score = d["selection_score"]
        geo = -np.sqrt(d[f"{key}_hold_front"].mean(1) * d[f"{key}_hold_side"].mean(1))
        assert d["timesteps"].tolist() == [128, 256, 384]
        # both errors are recorded whatever selects, and they differ
        assert not np.allclose(d["three_sigma_mdeg_hold_side"], d["pointing_three_sigma_mdeg_hold_side"])
    np.testing.assert_allclose(score, geo)
    best = load_policy(run_dir / "eval" / "best")
    res = run_task(best, DSS14_TASKS[0], [1000], 300)
    k = int(np.argmax(score))
    with np.load(run_dir / "eval" / "evaluations.npz") as d:
        np.testing.assert_allclose(res[key], d[f"{key}_hold_front"][k], rtol=1e-6)


# ------------------------------------------------------------------------------ scoring
def test_campaign_scoring_equals_the_benchmark_runner() -> None:
    """run_task (the campaign's test scoring, batched through act_batch) gives the runner's 3σ
    servo and pointing errors for a policy trained at another action scale (converted on the
    way)."""
    import torch

    from dss14_env.agents.algos import build_policy
    from dss14_env.agents.storage import NormStats

    cfg = load_config("ppo_plain")
    torch.manual_seed(0)
    policy = build_policy(cfg, 40, [-1.0, -1.0], [1.0, 1.0])
    stats = NormStats(np.zeros(40), np.full(40, 1e-2), 1.0, 1.0, 1e-8)
    ctrl = PolicyController(policy, cfg, stats, "test")
    steps = 400
    res = run_task(ctrl, DSS14_TASKS[1], [0, 1], steps, access=FINAL_SCORING)
    bench = run([("test", lambda env: PolicyController(policy, cfg, stats, "test", env))],
                ["hold_side"], seeds=[0, 1], steps=steps)
    ref = [e["servo_error_mdeg"]["az"]["three_sigma"] for e in bench["episodes"]]
    np.testing.assert_allclose(res["three_sigma_mdeg"], ref, rtol=1e-6)  # float32 BLAS order
    ref_p = [e["pointing_error_mdeg"]["xel"]["three_sigma"] for e in bench["episodes"]]
    np.testing.assert_allclose(res["pointing_three_sigma_mdeg"], ref_p, rtol=1e-6)
    assert DSS14_TASKS[1].pointing_axis == "xel" and not res["terminated"].any()


@pytest.mark.parametrize("features", [("command", "disturbance"), ("law", "command")])
def test_peek_is_what_observe_would_return(features: tuple) -> None:
    """The terminal-observation path (batched LQG, or one LQG per row for the LQR state)."""
    import copy

    cfg = gym.make("DSS14-Hold-v0").unwrapped.config
    spec = InterfaceSpec(base="lqg", action="residual", residual_scale=0.02, lqg_features=features,
                         history=2)
    itf = PolicyInterface(spec, cfg, 3)
    seqs = np.stack([_hold_observations(60, s) for s in (1, 2, 3)], 1)
    for obs in seqs[:-1]:
        itf.observe(obs)
    rows = np.array([0, 2])
    peeked = itf.peek(seqs[-1][rows], rows)
    want = copy.deepcopy(itf).observe(seqs[-1])[rows]
    np.testing.assert_array_equal(peeked, want)
    np.testing.assert_array_equal(itf.observe(seqs[-1])[rows], want)  # peek changed nothing
