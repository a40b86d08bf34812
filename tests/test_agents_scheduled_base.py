"""The policy interface on the pointing LQG scheduled on each row's mean wind speed reading."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dss14_env.agents.interface import InterfaceSpec, InterfaceWrapper
from dss14_env.baselines.scheduled import ScheduledPointingLQGController
from dss14_env.envs.config import load_env_config

pytest.importorskip("stable_baselines3")

from dss14_env.agents.vec_env import InterfaceVecEnv, make_sb3_vec_env  # noqa: E402
from dss14_env.agents.wind_readings import wind_source  # noqa: E402

SPEC = InterfaceSpec(base="lqg_pointing_sched", action="residual", residual_scale=0.01,
                     lqg_features=("command", "disturbance"), context=("axis_encoders", "wind_reading"))
KMH = 1 / 3.6


def _design_speeds(iface) -> np.ndarray:
    return np.asarray(iface.lqg_batch.info_batch["design_wind_speed_mps"], float)


def test_restart_forgets_the_ended_episodes_reading() -> None:
    """A batch row that restarts must not design its next episode for the last one's reading."""
    env_cfg = load_env_config(scenario="hold")
    from dss14_env.envs.vector import DSS14VectorEnv

    env = DSS14VectorEnv(2, scenario="hold", wind_speed_kmh=50.0)
    obs, _ = env.reset(seed=3)
    c = ScheduledPointingLQGController(env_cfg)
    c.reset_batch(2)
    c.set_scenario_batch([10 * KMH, 10 * KMH])
    c.act_batch(obs)
    assert np.allclose(c.info_batch["design_wind_speed_mps"], 10 * KMH)
    c.restart(np.array([True, False]))
    c.act_batch(obs)
    # row 0: no reading for its new episode -> the speed inferred from the start command (50 km/h
    # wind: the 50-km/h point), not the 10 km/h it had
    assert math.isnan(c.info_batch["wind_reading_mps"][0])
    assert c.info_batch["design_wind_speed_mps"][0] == pytest.approx(50 * KMH)
    assert c.info_batch["design_wind_speed_mps"][1] == pytest.approx(10 * KMH)
    c.restart(np.array([False, True]))
    c.set_row_readings([1], [70 * KMH])
    c.act_batch(obs)
    assert c.info_batch["design_wind_speed_mps"][1] == pytest.approx(70 * KMH)
    with pytest.raises(ValueError, match="rows must lie in 0..1"):
        c.set_row_readings([2], [1.0])


def test_rows_follow_their_own_readings_over_autoresets() -> None:
    """Each row's base is designed for its own environment's reading, refreshed at its autoreset."""
    env_cfg = load_env_config(scenario="hold")
    venv = make_sb3_vec_env("DSS14-Hold-v0", 4, seed=10_000, max_episode_steps=3, wind_speed_kmh="random",
                            wind_speed_grid_kmh=[10.0, 30.0, 70.0])
    iv = InterfaceVecEnv(venv, SPEC, env_cfg)
    iv.interface.wind_source = wind_source(venv)
    iface = iv.interface
    grid = np.asarray(iface.lqg_batch.grid_speeds)
    iv.reset()
    seen = []
    for _ in range(12):
        readings = venv.venv.wind_speeds_mps
        expect = grid[np.argmin(np.abs(grid[None] - readings[:, None]), axis=1)]
        assert np.allclose(_design_speeds(iface), expect)
        assert np.allclose(iface.wind_readings, readings)
        assert np.allclose(iface.context[:, 1], readings / (90 / 3.6))  # the policy sees it too
        seen.append(_design_speeds(iface))
        iv.step_async(np.zeros((4, 2), np.float32))
        iv.step_wait()
    seen = np.array(seen)
    # some row's design changed with a new episode's speed
    assert any(len(np.unique(np.round(seen[:, i], 6))) > 1 for i in range(4))


def test_single_env_reads_its_reset_info() -> None:
    import gymnasium as gym

    env = InterfaceWrapper(gym.make("DSS14-Hold-v0", wind_speed_kmh=10.0), SPEC)
    env.reset(seed=5)
    assert env.interface.wind_readings[0] == pytest.approx(10 * KMH)
    assert _design_speeds(env.interface)[0] == pytest.approx(10 * KMH)


def test_scheduled_base_refuses_the_per_row_features() -> None:
    with pytest.raises(ValueError, match="lqg_features: base lqg_pointing_sched"):
        InterfaceSpec(base="lqg_pointing_sched", action="residual", lqg_features=("output",))


def test_a_scored_policy_takes_the_episode_loops_readings() -> None:
    """The shipped general policy (on the scheduled base) is told each episode's reading by the
    bench's episode loop: one per row in a batch, and one kept over the episodes of ``act``."""
    from dss14_env.agents.policy import load_policy, shipped_policy

    ctrl = load_policy(shipped_policy("ppo_general"))
    assert ctrl.spec.base == "lqg_pointing_sched"
    ctrl.reset_batch(2)
    ctrl.set_scenario_batch([10 * KMH, 70 * KMH], [0.0, 0.0])
    assert np.allclose(ctrl.interface.wind_readings, [10 * KMH, 70 * KMH])
    ctrl.set_scenario(30 * KMH, 0.0)  # the sequential loop: before reset, kept over episodes
    ctrl.reset()
    assert ctrl.interface.wind_readings[0] == pytest.approx(30 * KMH)
    with pytest.raises(ValueError, match="wind speed reading"):
        ctrl.set_scenario_batch([1.0, 2.0])  # two readings for one row
