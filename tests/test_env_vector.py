"""Tests of the numpy-batched vector environment (:mod:`dss14_env.envs.vector`)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.vector import DSS14VectorEnv

#: info entries compared between the single and the vector env (also at resets)
INFO = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg", "measured_error_el_mdeg",
        "pointing_error_el_mdeg", "pointing_error_xel_mdeg", "wind_speed_mps", "wind_direction_rad",
        "rate_command_az_deg_s", "rate_command_el_deg_s")
# (config, constant action or None for small random ones, episode length): the second makes
# sub-environments hit the elevation limit at different steps, so autoresets desynchronise them;
# the last truncates episodes at the end of their first noise block, so that a block falls due
# on the step that resets them, beside desynchronised ones
CASES = {
    "track-random-wind-encoder-noise": (dict(scenario="track", wind_speed_kmh="random",
                                             wind_direction="random", encoder_noise_mdeg=0.1), None, 400),
    "hold-terminating-at-el-limit": (dict(scenario="hold", wind_speed_kmh="random",
                                          start_el_deg="random", start_el_range_deg=[6.05, 6.5]), -0.5, 400),
    "slew-exact-encoders": (dict(scenario="slew", wind_speed_kmh=30.0, encoder_bits=None), None, 400),
    "hold-truncating-at-a-block-end": (dict(scenario="hold", wind_speed_kmh="random", start_el_deg="random",
                                            start_el_range_deg=[6.05, 9.0], encoder_noise_mdeg=0.1),
                                       -0.3, 256),
    "monopulse-late-held-terminating": (dict(scenario="hold", wind_speed_kmh="random", start_el_deg="random",
                                             start_el_range_deg=[6.05, 9.0], encoder_noise_mdeg=0.1,
                                             sensors=["encoders", "monopulse"], monopulse_latency_s=0.1,
                                             monopulse_update_s=0.04, monopulse_cnr_dbhz=20.0),
                                        -0.3, 256),
}


def _actions(const: float | None, T: int, N: int) -> np.ndarray:
    if const is None:
        return np.random.default_rng(1).uniform(-0.02, 0.02, (T, N, 2)).astype(np.float32)
    return np.full((T, N, 2), const, np.float32)


@pytest.mark.parametrize("case", CASES)
def test_vector_env_equals_single_envs_with_seeds_seed_plus_i(case: str) -> None:
    # seeding rule: sub-environment i == a single env reset with seed + i; NEXT_STEP autoreset;
    # 700 steps cross two noise blocks of 256 steps, episodes end at max_steps or earlier
    kw, const, max_steps = CASES[case]
    N, T, seed = 3, 700, 10
    info_keys = INFO + (("monopulse_el_mdeg", "monopulse_xel_mdeg") if "sensors" in kw else ())
    acts = _actions(const, T, N)
    venv = DSS14VectorEnv(num_envs=N, max_episode_steps=max_steps, **kw)
    obs, info = venv.reset(seed=seed)
    v_obs, v_rew, v_term, v_trunc, v_info = [obs], [], [], [], [np.stack([info[k] for k in info_keys], 1)]
    for t in range(T):
        obs, r, te, tr, info = venv.step(acts[t])
        v_obs.append(obs), v_rew.append(r), v_term.append(te), v_trunc.append(tr)
        v_info.append(np.stack([info[k] for k in info_keys], 1))
    v_obs, v_rew, v_term, v_trunc, v_info = map(np.array, (v_obs, v_rew, v_term, v_trunc, v_info))
    for i in range(N):
        env = DSS14Env(**kw)
        obs, info = env.reset(seed=seed + i)
        s_obs, s_rew, s_term, s_trunc, s_info = [obs], [], [], [], [[info[k] for k in info_keys]]
        done = False
        for t in range(T):
            if done:  # the vector env's autoreset step
                obs, info = env.reset()
                r, te, tr, done = 0.0, False, False, False
            else:
                obs, r, te, tr, info = env.step(acts[t, i])
                tr = env.elapsed_steps >= max_steps
                done = te or tr
            s_obs.append(obs), s_rew.append(r), s_term.append(te), s_trunc.append(tr)
            s_info.append([info[k] for k in info_keys])
        assert np.array_equal(np.array(s_term), v_term[:, i])
        assert np.array_equal(np.array(s_trunc), v_trunc[:, i])
        np.testing.assert_allclose(np.array(s_obs), v_obs[:, i], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(np.array(s_rew), v_rew[:, i], rtol=1e-9, atol=1e-12)
        # batched and single products sum in different orders: the mdeg errors differ by up to
        # 3e-9 mdeg (5e-14 rad, tens of ulp of the angles they are differences of), measured
        np.testing.assert_allclose(np.array(s_info), v_info[:, i], rtol=1e-7, atol=1e-8)
    if case == "hold-terminating-at-el-limit":
        assert v_term.sum() >= N  # the desynchronising terminations did happen
    if case == "hold-truncating-at-a-block-end":  # both kinds of episode end did happen
        assert v_term.sum() >= 1 and v_trunc.sum() >= 1


def test_make_vec_vector_entry_point_equals_the_sync_vector_env() -> None:
    N, T = 3, 60
    acts = _actions(None, T, N)
    a = gym.make_vec("DSS14-v0", num_envs=N, vectorization_mode="vector_entry_point")
    b = gym.make_vec("DSS14-v0", num_envs=N, vectorization_mode="sync")
    assert isinstance(a, DSS14VectorEnv) and a.max_episode_steps == 3000
    oa, _ = a.reset(seed=7)
    ob, _ = b.reset(seed=7)
    np.testing.assert_allclose(oa, ob, rtol=1e-6, atol=1e-6)
    for t in range(T):
        oa, ra, *_ = a.step(acts[t])
        ob, rb, *_ = b.step(acts[t])
    np.testing.assert_allclose(oa, ob, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(ra, rb, rtol=1e-9)


def test_one_plant_per_wind_speed_groups_the_batch() -> None:
    venv = DSS14VectorEnv(num_envs=64, max_episode_steps=100, scenario="track", wind_speed_kmh="random",
                          wind_direction="random")
    venv.reset(seed=0)
    speeds = {p.wind_speed for p in venv._plants}
    assert len(venv._plants) == len(speeds) == 5  # directions do not need plants of their own
    assert sum(b - a for _, a, b in venv._groups) == 64


@pytest.mark.parametrize("actions, match", [
    (np.full((4, 2), np.nan, np.float32), "finite"),
    (np.zeros((3, 2), np.float32), "shape"),
    (np.zeros(8, np.float32), "shape"),
])
def test_vector_env_rejects_bad_actions(actions: np.ndarray, match: str) -> None:
    venv = DSS14VectorEnv(num_envs=4, max_episode_steps=10)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        venv.step(actions)


@pytest.mark.parametrize("kw, match", [
    (dict(num_envs=0), "num_envs"),
    (dict(num_envs=2, max_episode_steps=0), "max_episode_steps"),
    (dict(num_envs=2, render_mode="rgb_array"), "render"),
    (dict(num_envs=2, dt=-1.0), "dt"),
    (dict(num_envs=2, compiled=False), "^compiled must be None or True"),
    (dict(num_envs=2, compiled="yes"), "^compiled must be None or True"),
])
def test_vector_env_rejects_bad_arguments(kw: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        DSS14VectorEnv(**kw)


def test_vector_env_info_arrays_and_counters() -> None:
    venv = DSS14VectorEnv(num_envs=5, max_episode_steps=50, scenario="hold", wind_speed_kmh=50.0)
    venv.reset(seed=0)
    _, _, _, _, info = venv.step(np.ones((5, 2), np.float32))
    for key in ("servo_error_az_mdeg", "measured_error_el_mdeg", "pointing_error_xel_mdeg", "wind_speed_mps",
                "rate_command_az_deg_s", "accel_limited"):
        assert info[key].shape == (5,)
    assert info["action_unclipped"].shape == (5, 2)
    assert np.all(info["accel_limited"]) and np.all(venv.n_accel_limited == 1)
    assert np.all(info["n_accel_limited"] == 1)
    assert np.allclose(info["wind_speed_mps"], 50 / 3.6)


@pytest.mark.parametrize("kw", [
    dict(),
    dict(scenario="slew", randomize_params=True, wind_speed_kmh="random", start_el_deg="random"),
], ids=["defaults", "drawn-params-and-starts"])
def test_vector_reset_info_has_the_single_env_reset_info_per_sub_env(kw: dict) -> None:
    N, seed = 3, 4
    _, v_info = DSS14VectorEnv(num_envs=N, **kw).reset(seed=seed)
    for i in range(N):
        _, s_info = DSS14Env(**kw).reset(seed=seed + i)
        assert list(v_info) == list(s_info)
        for key, value in s_info.items():
            assert v_info[key].shape == (N,)
            if isinstance(value, float):
                assert v_info[key][i] == pytest.approx(value, rel=1e-7, abs=1e-9), key
            else:
                assert v_info[key][i] == value, key
    if kw.get("randomize_params"):
        assert all(len(p) > 0 for p in v_info["params"]) and len({str(p) for p in v_info["params"]}) == N


def test_reset_now_starts_the_episode_the_autoreset_would() -> None:
    """reset_now(idx) makes the next episode's draws at once: the first observation equals the
    one the NEXT_STEP autoreset returns a step later, and the next step continues it."""
    kw = dict(num_envs=3, max_episode_steps=5, scenario="hold", wind_direction="side")
    now, later = DSS14VectorEnv(**kw), DSS14VectorEnv(**kw)
    now.reset(seed=[1, 2, 3])
    later.reset(seed=[1, 2, 3])
    a = np.full((3, 2), 0.01)
    for _ in range(5):
        done = now.step(a)[3]
        later.step(a)
    assert done.all()
    first = now.reset_now(np.arange(3))
    auto, rew = later.step(a)[:2]
    np.testing.assert_array_equal(first, auto)
    assert (rew == 0.0).all()
    obs_now, rew_now, _, trunc_now, _ = now.step(a)
    obs_later, rew_later, _, trunc_later, _ = later.step(a)
    np.testing.assert_array_equal(obs_now, obs_later)
    np.testing.assert_array_equal(rew_now, rew_later)
    assert not trunc_now.any() and not trunc_later.any()


def test_wind_speeds_are_each_rows_reset_info_through_autoresets() -> None:
    """``wind_speeds_mps`` is every row's reset-info mean wind speed, and follows a row into its
    next episode at an autoreset (the info of the step that resets it)."""
    from dss14_env.envs.vector import DSS14VectorEnv

    env = DSS14VectorEnv(4, max_episode_steps=2, scenario="hold", wind_speed_kmh="random",
                         wind_speed_grid_kmh=[10.0, 30.0, 50.0, 70.0])
    _, info = env.reset(seed=3)
    assert np.array_equal(env.wind_speeds_mps, info["wind_speed_mps"])
    seen = [env.wind_speeds_mps]
    for _ in range(9):
        _, _, _, _, info = env.step(np.zeros((4, 2), np.float32))
        assert np.array_equal(env.wind_speeds_mps, info["wind_speed_mps"])
        seen.append(env.wind_speeds_mps)
    assert len(np.unique(np.round(seen, 9))) > 1  # new episodes drew other speeds
    env.wind_speeds_mps[:] = -1.0  # a copy: the environment's own is untouched
    assert (env.wind_speeds_mps >= 0).all()
