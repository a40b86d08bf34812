"""Tests of the DSS14 Gymnasium environment's interface (:mod:`dss14_env.envs.env`)."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.envs.config import EPISODE_KEYS, load_env_config
from dss14_env.envs.core import OBS, OBS_SIZE
from dss14_env.envs.env import OBS_NAMES, DSS14Env
from dss14_env.envs.vector import DSS14VectorEnv
from dss14_env.model.assembly import default_model
from dss14_env.model.uncertainty import SWEEP_PARAMS, draw_stable_params, pi_loop_abscissa, rate_loop_stable

IDS = ("DSS14-v0", "DSS14-Hold-v0", "DSS14-Step-v0", "DSS14-Slew-v0")
Q_MDEG = 360.0e3 / 2**20  # encoder count, mdeg


def _rollout(env: gym.Env, seed: int, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    obs, _ = env.reset(seed=seed)
    out, rew = [obs], []
    for a in actions:
        obs, r, term, trunc, _ = env.step(a)
        out.append(obs)
        rew.append(r)
        if term or trunc:
            break
    return np.array(out), np.array(rew)


# ---------------------------------------------------------------------------- registration
@pytest.mark.parametrize("env_id", IDS)
def test_registered_id_makes_the_env_with_its_time_limit(env_id: str) -> None:
    env = gym.make(env_id)
    assert isinstance(env.unwrapped, DSS14Env)
    assert env.spec.max_episode_steps == {"DSS14-Step-v0": 2000}.get(env_id, 3000)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)


def test_namespaced_module_id_works() -> None:
    env = gym.make("dss14_env:DSS14-v0")
    assert env.unwrapped.config.scenario == "track"


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_check_env_passes_without_warnings(env_id: str) -> None:
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)


@pytest.mark.parametrize("env_id", ("DSS14-v0", "DSS14-Step-v0"))
def test_sb3_check_env_passes_without_warnings(env_id: str) -> None:
    from stable_baselines3.common.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(env_id))


# ---------------------------------------------------------------------------- determinism
@pytest.mark.parametrize("env_id", ("DSS14-v0", "DSS14-Slew-v0"))
def test_same_seed_gives_the_same_trajectory(env_id: str) -> None:
    acts = np.random.default_rng(5).uniform(-0.05, 0.05, (300, 2)).astype(np.float32)
    o1, r1 = _rollout(gym.make(env_id, encoder_noise_mdeg=0.1), 42, acts)
    o2, r2 = _rollout(gym.make(env_id, encoder_noise_mdeg=0.1), 42, acts)
    assert np.array_equal(o1, o2) and np.array_equal(r1, r2)


def test_different_seeds_give_different_trajectories() -> None:
    acts = np.zeros((50, 2), np.float32)
    o1, _ = _rollout(gym.make("DSS14-Hold-v0"), 1, acts)
    o2, _ = _rollout(gym.make("DSS14-Hold-v0"), 2, acts)
    assert not np.array_equal(o1, o2)


def test_reset_without_seed_continues_the_generator() -> None:
    env = gym.make("DSS14-v0")
    env.reset(seed=3)
    _, i1 = env.reset()
    _, i2 = env.reset()
    assert (i1["start_az_deg"], i1["start_el_deg"]) != (i2["start_az_deg"], i2["start_el_deg"])


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("action, match", [
    (np.array([np.nan, 0.0], np.float32), "finite"),
    (np.array([0.0, np.inf], np.float32), "finite"),
    (np.array([-np.inf, 0.0]), "finite"),
    (np.zeros(3, np.float32), "shape"),
    (np.zeros((2, 1), np.float32), "shape"),
    (0.5, "shape"),
    (["a", "b"], "real numbers"),
    (np.array(["0.5", "1e3"]), "real numbers"),
    (np.array([0.5 + 0j, 0.0]), "real numbers"),
    ([10**400, 0], "real numbers"),
    (np.array([True, False]), "real numbers"),
    (np.array([0.1, 0.2], dtype=object), "real numbers"),
])
def test_bad_action_raises_value_error(action, match: str) -> None:
    env = DSS14Env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="^action must .*" + match):
        env.step(action)


def test_step_before_reset_raises() -> None:
    with pytest.raises(RuntimeError, match="reset"):
        DSS14Env().step(np.zeros(2, np.float32))


@pytest.mark.parametrize("key, value", [
    ("wind_speed_kmh", -10.0),
    ("wind_speed_kmh", "gale"),
    ("wind_direction", "north"),
    ("wind_direction", math.nan),
    ("scenario", "orbit"),
    ("dt", 0.0),
    ("dt", -0.02),
    ("dt", math.inf),
    ("encoder_bits", 3),
    ("encoder_noise_mdeg", -0.1),
    ("step_axes", "x"),
    ("step_time_s", 0.0),
    ("el_limits_deg", [88.0, 6.0]),
    ("start_el_deg", 3.0),
    ("track_amp_max_deg", 50.0),
    ("slew_rate_deg_s", 1.0),
    ("randomize_params", "yes"),
    ("params", {"hydraulics.beta": 1.0}),
    ("wind_speed_grid_kmh", []),
])
def test_bad_config_value_raises_naming_the_key(key: str, value) -> None:
    with pytest.raises(ValueError, match=key):
        DSS14Env(**{key: value})


@pytest.mark.parametrize("key, value", [
    ("wind_speed_kmh", 1e5),            # once NaN observations forever (vector) / a crash (single)
    ("wind_speed_kmh", 3000.0),         # once blamed on dt
    ("wind_speed_kmh", 90.5),           # beyond the operating range the model is meant for
    ("wind_speed_grid_kmh", [30.0, 1e5]),
    ("error_scale_mdeg", 1e-300),       # once an infinite reward
    ("dt", 1e-300),
    ("action_scale_deg_s", 1e-300),
    ("rate_limit_deg_s", 1e300),
    ("accel_limit_deg_s2", 1e300),
    ("encoder_noise_mdeg", 1e300),
    ("action_change_weight", 1e308),
    ("termination_penalty", 1e308),
    ("track_period_range_s", [1e-320, 600.0]),
    ("slew_accel_deg_s2", 1e-320),
    ("slew_rate_deg_s", 1e-320),
    ("step_deg", 1e200),
    ("az_wrap_centre_deg", 1e300),
    ("start_az_deg", 300.0),
    ("start_el_range_deg", [1.0, 50.0]),
    ("render_window_s", 1e300),
])
def test_unphysical_values_are_refused_by_both_envs(key: str, value) -> None:
    with pytest.raises(ValueError, match=f"field '{key}'"):
        DSS14Env(**{key: value})
    with pytest.raises(ValueError, match=f"field '{key}'"):
        DSS14VectorEnv(num_envs=2, **{key: value})
    if key in EPISODE_KEYS:
        env = DSS14Env()
        with pytest.raises(ValueError, match=f"reset options: field '{key}'"):
            env.reset(seed=0, options={key: value})


def test_scientific_notation_is_a_number_in_files_and_a_string_is_not(tmp_path) -> None:
    path = tmp_path / "env.yaml"
    path.write_text("dt: 1e-2\nerror_scale_mdeg: 1e1\n")  # YAML 1.1 alone reads 1e-2 as a string
    cfg = load_env_config(path, encoder_noise_mdeg=5e-2)
    assert (cfg.dt, cfg.error_scale_mdeg, cfg.encoder_noise_mdeg) == (0.01, 10.0, 0.05)
    with pytest.raises(ValueError, match="field 'encoder_noise_mdeg': .* got '5e-2'"):
        load_env_config(path, encoder_noise_mdeg="5e-2")
    path.write_text("dt: '1e-2'\n")  # quoted: a string
    with pytest.raises(ValueError, match=f"{path}: field 'dt': .* got '1e-2'"):
        load_env_config(path)


def test_config_file_errors_name_the_file_and_the_key(tmp_path) -> None:
    path = tmp_path / "env.yaml"
    path.write_text("dt: fast\n")
    with pytest.raises(ValueError, match=f"{path}: field 'dt': must be a number"):
        DSS14Env(config=path)
    path.write_text("dt: [0.02\n")
    with pytest.raises(ValueError, match=f"{path}: not valid YAML"):
        DSS14Env(config=path)


def test_unknown_config_key_raises_naming_it() -> None:
    with pytest.raises(ValueError, match="wind_speed_mph"):
        DSS14Env(wind_speed_mph=30.0)


@pytest.mark.parametrize("options, match", [
    ({"wind_speed_kmh": -1.0}, "wind_speed_kmh"),
    ({"scenario": "orbit"}, "scenario"),
    ({"wind_direction": "north"}, "wind_direction"),
    ({"dt": 0.01}, "dt"),  # not an episode key
    ({"foo": 1}, "foo"),
    ({1: 2}, "^reset options: field 1: must be an episode key"),  # not a string: named, not a KeyError
    ({None: "x" * 500}, r"^reset options: field None: must be an episode key .*\.\.\.$"),
])
def test_bad_reset_option_raises_naming_it(options: dict, match: str) -> None:
    env = DSS14Env()
    with pytest.raises(ValueError, match=match) as err:
        env.reset(seed=0, options=options)
    assert "\n" not in str(err.value)


def test_reset_options_apply_to_one_episode_only() -> None:
    env = DSS14Env(scenario="track", wind_speed_kmh=50.0)
    _, info = env.reset(seed=0, options={"scenario": "hold", "wind_speed_kmh": 70.0,
                                         "wind_direction": "side"})
    assert info["scenario"] == "hold" and info["wind_speed_mps"] == pytest.approx(70 / 3.6)
    assert info["wind_direction_rad"] == pytest.approx(math.pi / 2)
    _, info = env.reset()
    assert info["scenario"] == "track" and info["wind_speed_mps"] == pytest.approx(50 / 3.6)
    assert set(EPISODE_KEYS) <= set(load_env_config().__dataclass_fields__)


# ---------------------------------------------------------------------------- observation, info
def test_observation_layout_matches_info_and_command() -> None:
    env = DSS14Env(scenario="track", wind_speed_kmh=50.0, encoder_bits=None)
    obs, _ = env.reset(seed=1)
    cfg = env.config
    assert len(OBS_NAMES) == obs.shape[0] == OBS_SIZE == 12
    # the documented table (DSS14Env): pairs [az, el] in this order
    assert [(OBS_NAMES[2 * i], getattr(OBS, f)) for i, f in enumerate(OBS._fields)] == [
        ("error_az", slice(0, 2)), ("error_rate_az", slice(2, 4)), ("command_az", slice(4, 6)),
        ("command_rate_az", slice(6, 8)), ("encoder_az", slice(8, 10)), ("prev_rate_az", slice(10, 12))]
    for _ in range(20):
        obs, _, _, _, info = env.step(np.array([0.01, -0.01], np.float32))
    err = obs[OBS.error] * cfg.error_scale_mdeg
    assert err[0] == pytest.approx(info["measured_error_az_mdeg"], rel=1e-6)
    assert err[1] == pytest.approx(info["measured_error_el_mdeg"], rel=1e-6)
    # exact encoders: measured == true error; servo error = command - encoder (both in deg)
    assert info["measured_error_az_mdeg"] == pytest.approx(info["servo_error_az_mdeg"], abs=1e-9)
    c_minus_enc = (obs[OBS.command][0] - obs[OBS.encoder][0]) * 1e3
    assert c_minus_enc == pytest.approx(info["servo_error_az_mdeg"], abs=1e-3)
    rate = obs[OBS.prev_rate][0] * cfg.rate_limit_deg_s
    assert rate == pytest.approx(info["rate_command_az_deg_s"], rel=1e-6)


@pytest.mark.parametrize("bits", [20, 16])
def test_quantised_encoder_error_is_within_half_a_count(bits: int) -> None:
    env = DSS14Env(scenario="hold", wind_speed_kmh=50.0, encoder_bits=bits)
    env.reset(seed=2)
    half = 0.5 * 360.0e3 / 2**bits
    diffs = []
    for _ in range(200):
        _, _, _, _, info = env.step(np.zeros(2, np.float32))
        diffs.append(info["measured_error_az_mdeg"] - info["servo_error_az_mdeg"])
    diffs = np.abs(diffs)
    assert diffs.max() <= half * (1 + 1e-6)
    assert diffs.max() > 0.3 * half  # the readings really are quantised


def test_command_limiter_limits_rate_change_and_counts_hits() -> None:
    env = DSS14Env(scenario="hold", wind_speed_kmh=0.0)
    obs, _ = env.reset(seed=0)
    cfg = env.config
    dr = cfg.accel_limit_deg_s2 * cfg.dt
    prev = obs[10] * cfg.rate_limit_deg_s
    for _ in range(3):
        obs, _, _, _, info = env.step(np.array([1.0, -5.0], np.float32))
        assert info["accel_limited"] and not info["rate_limited"]
        assert info["action_unclipped"] == (1.0, -5.0)
        assert info["rate_command_az_deg_s"] - prev == pytest.approx(dr, rel=1e-9)
        prev = info["rate_command_az_deg_s"]
    assert env.n_accel_limited == info["n_accel_limited"] == 3 and info["n_rate_limited"] == 0


def test_rate_clip_acts_when_the_action_scale_exceeds_the_rate_limit() -> None:
    env = DSS14Env(scenario="hold", wind_speed_kmh=0.0, action_scale_deg_s=1.0, accel_limit_deg_s2=100.0)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([1.0, 0.0], np.float32))
    assert info["rate_limited"] and info["rate_command_az_deg_s"] == pytest.approx(0.25)


def test_reward_is_the_documented_quadratic() -> None:
    env = DSS14Env(scenario="hold", wind_speed_kmh=50.0, action_change_weight=2.0)
    env.reset(seed=4)
    a_prev = None
    for a in ([0.0, 0.0], [0.002, -0.001], [0.003, 0.004]):
        a = np.array(a, np.float32)
        _, r, _, _, info = env.step(a)
        if a_prev is not None:
            e2 = info["servo_error_az_mdeg"] ** 2 + info["servo_error_el_mdeg"] ** 2
            assert r == pytest.approx(-(e2 / 100.0 + 2.0 * float(np.sum((a - a_prev) ** 2))), rel=1e-6)
        a_prev = a.astype(np.float64)


@pytest.mark.parametrize("options, what", [
    ({"start_el_deg": 6.2}, "elevation"),
    ({"start_az_deg": 264.8}, "azimuth"),
])
def test_leaving_the_travel_terminates(options: dict, what: str) -> None:
    env = DSS14Env(scenario="hold", wind_speed_kmh=0.0)
    env.reset(seed=0, options=options)
    a = np.array([1.0, 0.0] if what == "azimuth" else [0.0, -1.0], np.float32)
    for k in range(2000):
        _, r, term, _, info = env.step(a)
        steps = k + 1
        if term:
            break
    assert term and r < -env.config.termination_penalty
    assert steps * env.config.dt < 20.0


def test_error_beyond_the_bound_terminates() -> None:
    env = DSS14Env(scenario="step", step_deg=1.5, wind_speed_kmh=0.0)
    env.reset(seed=0)
    for k in range(200):
        _, _, term, _, info = env.step(np.zeros(2, np.float32))
        steps = k + 1
        if term:
            break
    assert term and abs(info["servo_error_az_mdeg"]) > 1000.0
    assert steps * env.config.dt == pytest.approx(env.config.step_time_s)


def test_info_state_option_adds_the_plant_state() -> None:
    env = DSS14Env(info_state=True)
    _, info = env.reset(seed=0)
    n = env.episode.plant.n
    assert info["plant_state"].shape == (n,)
    _, _, _, _, info = env.step(np.zeros(2, np.float32))
    assert info["plant_state"].shape == (n,) and np.all(np.isfinite(info["plant_state"]))
    assert "plant_state" not in DSS14Env().reset(seed=0)[1]


# ---------------------------------------------------------------------------- randomisation
def test_randomised_parameters_lie_in_the_stable_part_of_the_ranges() -> None:
    model = default_model()
    rng = np.random.default_rng(0)
    draws = [draw_stable_params(rng) for _ in range(8)]
    for d in draws:
        assert set(d) == set(SWEEP_PARAMS)
        for name, v in d.items():
            lo, hi = model.cfg.params[name].range
            assert lo <= v <= hi
    assert len({d["hydraulics.mu"] for d in draws}) == 8
    from dss14_env.model.uncertainty import perturbed_rate_loop

    rl = perturbed_rate_loop(model, draws[0])
    assert rate_loop_stable(rl.A) and pi_loop_abscissa(rl, *model.gains("kp1")) < 0


def test_randomize_params_changes_the_plant_per_reset() -> None:
    env = DSS14Env(scenario="hold", randomize_params=True)
    _, i1 = env.reset(seed=0)
    _, i2 = env.reset()
    assert i1["params"] and i1["params"] != i2["params"]
    for _ in range(50):
        obs, r, _, _, _ = env.step(np.zeros(2, np.float32))
    assert np.all(np.isfinite(obs)) and math.isfinite(r)
    assert DSS14Env().reset(seed=0)[1]["params"] == {}


# ---------------------------------------------------------------------------- rendering
def test_rgb_array_render_is_an_image_of_the_recent_history() -> None:
    env = gym.make("DSS14-v0", render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    for _ in range(100):
        env.step(np.full(2, 0.01, np.float32))
    frame = env.render()
    env.close()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    assert not np.array_equal(first, frame)


def test_render_history_holds_every_step_as_its_info() -> None:
    # across noise blocks and a snapshot restore: the samples are the steps' own values
    env = DSS14Env(render_mode="rgb_array", max_error_deg=90.0)
    env.reset(seed=3)
    acts = np.random.default_rng(3).uniform(-1.0, 1.0, (600, 2))
    rows = []
    for k, a in enumerate(acts):
        if k == 300:
            state = env.get_state()
        if k == 400:  # back to step 300: the history keeps the steps taken, the restored ones follow
            env.set_state(state)
        info = env.step(a)[4]
        rows.append((info["servo_error_az_mdeg"], info["servo_error_el_mdeg"], info["rate_command_az_deg_s"],
                     info["rate_command_el_deg_s"], env.episode.wind_speed + env.wind_gust()))
    env.render()
    h = np.array(env._renderer.samples)
    assert h.shape == (601, 8) and h[0, 0] == 0.0
    np.testing.assert_allclose(h[1:, 0], np.r_[1:401, 301:501] * env.config.dt, rtol=1e-15)
    np.testing.assert_allclose(h[1:, [1, 2, 3, 4, 7]], np.array(rows), rtol=1e-12, atol=1e-12)


def test_render_without_mode_warns_and_returns_none() -> None:
    env = DSS14Env()
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_bad_render_mode_raises() -> None:
    with pytest.raises(ValueError, match="render_mode"):
        DSS14Env(render_mode="ascii")


# ---------------------------------------------------------------------------- configuration
def test_config_from_a_yaml_file_and_a_mapping(tmp_path) -> None:
    path = tmp_path / "env.yaml"
    path.write_text("scenario: step\nstep_deg: 0.05\nwind_speed_kmh: 0\n")
    cfg = load_env_config(path, dt=0.01)
    assert (cfg.scenario, cfg.step_deg, cfg.dt, cfg.rate_limit_deg_s) == ("step", 0.05, 0.01, 0.25)
    env = DSS14Env(config={"scenario": "hold", "encoder_bits": None})
    assert env.config.scenario == "hold" and env.config.encoder_bits is None
    with pytest.raises(ValueError, match="not found"):
        load_env_config(tmp_path / "missing.yaml")


def test_wind_gust_is_zero_without_wind_and_varies_in_wind() -> None:
    calm = DSS14Env(scenario="hold", wind_speed_kmh=0.0)
    calm.reset(seed=0)
    calm.step(np.zeros(2, np.float32))
    assert calm.wind_gust() == 0.0
    windy = DSS14Env(scenario="hold", wind_speed_kmh=50.0)
    windy.reset(seed=0)
    gusts = [windy.step(np.zeros(2, np.float32)) and windy.wind_gust() for _ in range(100)]
    assert 0.1 < np.std(gusts) < 5.0  # m/s; sigma_u of the Davenport spectrum is 2.4 m/s at 50 km/h
