"""The wind-scheduled pointing LQG (baselines/scheduled.py): lqg_pointing at its own design wind,
the light-wind design at 10 km/h, batches of rows with different readings, bad readings and a
bad schedule refused, and a run through the bench's runner."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from dss14_env.baselines.design import ConfigError, infer_wind, load_controllers_config
from dss14_env.baselines.lqg import PointingLQGController
from dss14_env.baselines.scheduled import ScheduledPointingLQGController
from dss14_env.bench import runner
from dss14_env.bench.grid import grid_scenario
from dss14_env.core.units import KMH
from dss14_env.envs.env import DSS14Env

STEPS = 150
SHIPPED = Path(__file__).resolve().parents[1] / "configs" / "controllers.yaml"


def _env(speed_kmh: float, direction_deg: float = 0.0) -> DSS14Env:
    return DSS14Env(**grid_scenario(direction_deg, speed_kmh, 10.0).env)


def _actions(ctrl, speed_kmh: float, seed: int, reading: float | None = None) -> np.ndarray:
    """The controller's actions on one hold episode (``reading``: the anemometer's, m/s)."""
    env = _env(speed_kmh)
    obs, _ = env.reset(seed=seed)
    if reading is not None:
        ctrl.set_scenario(reading)
    ctrl.reset(seed)
    out = []
    for _ in range(STEPS):
        a = ctrl.act(obs)
        out.append(a)
        obs, _, terminated, _, _ = env.step(a)
        assert not terminated
    return np.array(out)


@pytest.fixture(scope="module")
def sched() -> ScheduledPointingLQGController:
    return ScheduledPointingLQGController(_env(50.0))


def test_equals_lqg_pointing_at_its_design_wind(sched: ScheduledPointingLQGController) -> None:
    """A 50-km/h reading: the design of lqg_pointing, the same actions bit for bit."""
    ref = _actions(PointingLQGController(_env(50.0)), 50.0, seed=3)
    got = _actions(sched, 50.0, seed=3, reading=50 * KMH)
    assert np.array_equal(got, ref)
    assert sched.info["design_wind"][0] == load_controllers_config(SHIPPED).design.wind_speed


def test_light_wind_takes_the_light_wind_design(sched: ScheduledPointingLQGController) -> None:
    """A 10-km/h reading picks the grid's 10-km/h point: a gust model at 10 km/h and the point's
    measurement noise in the Kalman design (from the file), and other actions than
    lqg_pointing's on the same episode."""
    cfg = load_controllers_config(SHIPPED)
    sc = cfg.schedule
    i = [round(s / KMH, 6) for s in sc.wind_speeds].index(10.0)
    got = _actions(sched, 10.0, seed=5, reading=10 * KMH)
    assert sched.info["design_wind"][0] == 10 * KMH
    wind = sched.design.dm.wind  # ("design", speed): direction-free; (speed, direction)
    assert (wind[1] if wind[0] == "design" else wind[0]) == 10 * KMH
    noise = math.hypot(sched.interface.encoder_noise, sc.measurement_noise[i])
    q2 = sched.design.dm.R[0, 0] - noise ** 2  # the quantisation's q^2 / 12
    assert q2 == pytest.approx((2 * math.pi / 2 ** 20) ** 2 / 12, rel=1e-9)
    assert sc.measurement_noise[i] != cfg.lqg.measurement_noise
    assert sched.info["wind_reading_mps"] == 10 * KMH
    ref = _actions(PointingLQGController(_env(10.0)), 10.0, seed=5)
    assert not np.array_equal(got, ref)
    assert sched.grid_point(14 * KMH) == i and sched.grid_point(16 * KMH) == i + 1


def test_batch_rows_with_different_readings_act_as_alone(sched: ScheduledPointingLQGController) -> None:
    """Rows of one batch at 50 and 10 km/h (two designs, grouped) act exactly as the controller
    on each episode alone."""
    speeds, seeds = (50.0, 10.0), (2, 4)
    alone = [_actions(sched, v, s, reading=v * KMH) for v, s in zip(speeds, seeds, strict=True)]
    envs = [_env(v) for v in speeds]
    obs = np.stack([e.reset(seed=s)[0] for e, s in zip(envs, seeds, strict=True)])
    ctrl = ScheduledPointingLQGController(envs[0])
    ctrl.reset_batch(2, seeds=list(seeds))
    ctrl.set_scenario_batch([v * KMH for v in speeds])
    for k in range(STEPS):
        a = ctrl.act_batch(obs)
        for i, e in enumerate(envs):
            assert np.array_equal(a[i], alone[i][k])
            obs[i] = e.step(a[i])[0]
    assert len({id(d) for d in ctrl.designs}) == 2


@pytest.mark.parametrize("bad", [math.nan, -1.0, math.inf, 200.0, "fast", [3.0, 4.0]])
def test_bad_readings_are_refused_with_one_line(sched: ScheduledPointingLQGController, bad) -> None:
    with pytest.raises(ValueError, match="wind speed reading") as exc:
        sched.set_scenario(bad)
    assert "\n" not in str(exc.value)


def test_bad_batch_readings_are_refused(sched: ScheduledPointingLQGController) -> None:
    sched.reset_batch(2)
    for bad in ([1.0], [1.0, math.nan], [[1.0, 2.0]] * 2):
        with pytest.raises(ValueError, match="wind speed reading: 2 finite speeds"):
            sched.set_scenario_batch(bad)
    sched.reset()


@pytest.mark.parametrize(("edit", "match"), [
    ({"measurement_noise": [0.5, 0.1]}, "schedule.measurement_noise': needs one entry per wind speed"),
    ({"wind_speeds": [10.0, 30.0, 20.0, 50.0, 70.0]}, "schedule.wind_speeds': must be strictly ascending"),
    ({"wind_speeds": [0.0, 20.0, 30.0, 50.0, 70.0]}, "schedule.wind_speeds"),
])
def test_a_bad_schedule_is_refused_naming_the_field(tmp_path: Path, edit: dict, match: str) -> None:
    data = yaml.safe_load(SHIPPED.read_text())
    for key, value in edit.items():
        data["schedule"][key]["value"] = value
    path = tmp_path / "controllers.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=match) as exc:
        load_controllers_config(path)
    assert "\n" not in str(exc.value)


def test_runs_in_the_bench_batched_with_the_episodes_wind() -> None:
    """The catalog row through the runner: batched, and each episode's design from its reading."""
    sc = grid_scenario(90.0, 10.0, 6.0)
    res = runner.run(["lqg_pointing_sched"], [("light_side", sc)], [0, 1])
    assert res["meta"]["batched"]["lqg_pointing_sched"]
    assert [ep["failure"] for ep in res["episodes"]] == [None, None]
    assert all(math.isfinite(ep["pointing_error_mdeg"]["xel"]["three_sigma"]) for ep in res["episodes"])


def test_without_a_reading_the_start_command_gives_the_speed() -> None:
    """No anemometer reading: the episode's grid point is the one nearest to the speed inferred
    from its start command, and the info says there was no reading."""
    ctrl = ScheduledPointingLQGController(_env(70.0))
    env = _env(70.0)
    obs, _ = env.reset(seed=1)
    ctrl.reset(1)
    ctrl.act(obs)
    _, _, c_rate0, r0 = ctrl.reader.read(obs[None].astype(float))
    inferred = infer_wind(r0[0], c_rate0[0])[0]
    assert math.isnan(ctrl.info["wind_reading_mps"])
    assert ctrl.info["design_wind"][0] == ctrl.grid_speeds[ctrl.grid_point(inferred)]
