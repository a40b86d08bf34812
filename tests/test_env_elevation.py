"""Episodes start at the model's elevation, where its pointing outputs and cos(E) hold; the
start still draws the elevation encoder's quantisation phase.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dss14_env.envs.env import DSS14Env
from dss14_env.envs.plant import default_plant_factory
from dss14_env.envs.vector import DSS14VectorEnv

Q_DEG = 360.0 / 2**20  # one encoder count


def test_default_episodes_start_at_the_model_elevation_with_drawn_quantisation_phase() -> None:
    xel = default_plant_factory().xel_scale  # cos(E) of the pointing outputs
    env = DSS14Env()
    starts = np.array([env.reset(seed=s)[1]["start_el_deg"] for s in range(40)])
    # the episode's own cos(E) is the model's (the xel pointing error is the episode's)
    assert np.max(np.abs(np.cos(np.radians(starts)) / xel - 1.0)) < 2.5e-4
    phase = np.mod(starts / Q_DEG, 1.0)  # where the start sits between two counts
    assert np.ptp(starts) > 5 * Q_DEG and np.ptp(phase) > 0.5


def test_vector_env_starts_at_the_model_elevation_too() -> None:
    venv = DSS14VectorEnv(num_envs=8)
    _, info = venv.reset(seed=0)
    xel = default_plant_factory().xel_scale
    assert np.max(np.abs(np.cos(np.radians(info["start_el_deg"])) / xel - 1.0)) < 2.5e-4


def test_random_and_fixed_start_elevations_remain_available() -> None:
    env = DSS14Env(start_el_deg="random", start_el_range_deg=[20.0, 70.0])
    starts = [env.reset(seed=s)[1]["start_el_deg"] for s in range(20)]
    assert min(starts) < 35.0 and max(starts) > 55.0
    assert DSS14Env(start_el_deg=30.0).reset(seed=0)[1]["start_el_deg"] == pytest.approx(30.0)


@pytest.mark.parametrize("limits, inside", [([50.0, 88.0], 60.0), ([6.0, 40.0], 30.0)],
                         ids=["below", "above"])
def test_model_elevation_outside_the_travel_is_one_line_naming_the_key(limits: list[float],
                                                                       inside: float) -> None:
    env = DSS14Env(el_limits_deg=limits, start_el_range_deg=[inside - 2.0, inside + 2.0])
    shown = rf"\[{limits[0]:g}, {limits[1]:g}\]"
    with pytest.raises(ValueError, match=r"env.yaml: field 'start_el_deg': 'model' starts at the model's "
                                         rf"elevation 45 deg, outside el_limits_deg {shown}") as err:
        env.reset(seed=0)
    assert "\n" not in str(err.value)
    assert math.isfinite(env.reset(seed=0, options={"start_el_deg": inside})[1]["start_el_deg"])
