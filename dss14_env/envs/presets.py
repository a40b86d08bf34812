"""The named environment presets: one table behind the registered Gymnasium ids and the
benchmark's scenarios.

Each preset is a set of environment keys (on top of ``configs/env.yaml``), the episode length
of its registered id and the warm-up that statistics leave out.  ``import dss14_env`` registers
every preset's id (:func:`register_presets`; nothing is built); the benchmark's scenarios
(:data:`dss14_env.bench.catalog.SCENARIOS`) are the same presets by name.

>>> PRESETS["hold_front"].env_id, dict(PRESETS["hold_front"].kwargs)["wind_direction"]
('DSS14-HoldFront-v0', 'front')
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

#: wind directions of the random-direction presets, deg (0 = front)
EIGHT_DIRECTIONS = tuple(45.0 * i for i in range(8))


@dataclass(frozen=True)
class Preset:
    """One named environment configuration.

    :param env_id: the registered Gymnasium id
    :param kwargs: environment keys (``configs/env.yaml`` names) on top of the defaults
    :param max_episode_steps: truncation of the registered id, control periods (of the configured ``dt``)
    :param warmup_s: seconds at the start that error statistics leave out
    :param description: one line for tables and docs
    :param purpose: what the id is for (the manual's table of registered ids)
    :param loaded_axes: the axes its one fixed wind loads most (``"az"``, ``"el"``): the axis
        its figures are scored on (the bench's bold columns, the agents' evaluation tasks);
        empty without a fixed wind direction
    """

    env_id: str
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    max_episode_steps: int = 3000
    warmup_s: float = 0.0
    description: str = ""
    purpose: str = ""
    loaded_axes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "kwargs", MappingProxyType(dict(self.kwargs)))


#: the presets by name
PRESETS: Mapping[str, Preset] = MappingProxyType({
    "track": Preset("DSS14-v0", {"scenario": "track", "wind_speed_kmh": "random",
                                 "wind_direction": "random",
                                 "wind_direction_grid_deg": list(EIGHT_DIRECTIONS)},
                    3000, 5.0, "slow track, random 30-70 km/h wind and direction",
                    "the main task: track a slow trajectory in varied wind"),
    "hold": Preset("DSS14-Hold-v0", {"scenario": "hold", "wind_speed_kmh": 50.0,
                                     "wind_direction": "random",
                                     "wind_direction_grid_deg": [0.0, 90.0]},
                   3000, 5.0, "hold, 50 km/h front or side wind (drawn per episode)",
                   "wind rejection at the report's Table 4 conditions (the residual PPO's base)"),
    "hold_front": Preset("DSS14-HoldFront-v0", {"scenario": "hold", "wind_speed_kmh": 50.0,
                                                "wind_direction": "front"},
                         3000, 5.0, "hold, 50 km/h front wind (Table 4)",
                         "wind rejection in front wind: elevation loaded (bench scenario)", ("el",)),
    "hold_side": Preset("DSS14-HoldSide-v0", {"scenario": "hold", "wind_speed_kmh": 50.0,
                                              "wind_direction": "side"},
                        3000, 5.0, "hold, 50 km/h side wind (Table 4)",
                        "wind rejection in side wind: azimuth loaded (bench scenario)", ("az",)),
    "step": Preset("DSS14-Step-v0", {"scenario": "step", "step_deg": 0.1, "step_axes": "both",
                                     "wind_speed_kmh": 0.0},
                   2000, 0.0, "0.1 deg step on both axes at 1 s, no wind (Fig. 21)",
                   "transient response: overshoot and settling, acceleration limit active"),
    "slew": Preset("DSS14-Slew-v0", {"scenario": "slew", "slew_deg": 5.0, "wind_speed_kmh": 30.0,
                                     "wind_direction": "random",
                                     "wind_direction_grid_deg": list(EIGHT_DIRECTIONS)},
                   3000, 0.0, "5 deg slew on both axes, 30 km/h wind",
                   "large moves under the rate and acceleration limits"),
})

#: the learning agents' wrapper ids, registered on top of the presets by ``import dss14_env``
#: (:data:`dss14_env.agents.AGENT_ENV_IDS`), with what they are for (for the manual's table;
#: ``tests/test_env_docs.py`` fails when a registered id is missing here)
WRAPPED_IDS: Mapping[str, str] = MappingProxyType({
    "DSS14-Plain-v0": "plain RL: the policy alone sets the rate command, seeing the encoders and "
                      "the command without the absolute angles, with an 8-step history "
                      "(dss14_env.agents.envs)",
    "DSS14-Residual-v0": "PPO residual on the report's PI: a policy adds a small correction to the "
                         "PI's rate command and sees the PI's integral (dss14_env.agents.residual)",
    "DSS14-ResidualLQG-v0": "residual on the LQG: a policy corrects the LQG's rate command and sees "
                            "its command, disturbance and state estimate (dss14_env.agents.envs)",
    "DSS14-KalmanObs-v0": "a policy sets the rate command itself, seeing the LQG's command, "
                          "disturbance and state estimate (dss14_env.agents.envs)",
})

ENTRY_POINT = "dss14_env.envs.env:DSS14Env"
VECTOR_ENTRY_POINT = "dss14_env.envs.vector:DSS14VectorEnv"


def _wind(kw: Mapping[str, Any], defaults: Any) -> str:
    """The wind of a preset's keys ``kw`` on top of the configuration ``defaults``."""
    speed = kw.get("wind_speed_kmh", defaults.wind_speed_kmh)
    direction = kw.get("wind_direction", defaults.wind_direction)
    if speed == 0:
        return "none"
    if speed == "random":
        speeds = ", ".join(f"{v:g}" for v in kw.get("wind_speed_grid_kmh", defaults.wind_speed_grid_kmh))
        what = f"speed drawn from {speeds} km/h"
    else:
        what = f"{speed:g} km/h"
    if direction == "random":
        grid = kw.get("wind_direction_grid_deg", defaults.wind_direction_grid_deg)
        dirs = "front or side" if list(grid) == [0.0, 90.0] else f"{len(grid)} directions"
        return f"{what}, {dirs} (drawn)"
    return f"{what}, {direction}"


def registered_ids_table() -> str:
    """The markdown table of every registered id: the presets (scenario, wind, episode length,
    what it is for) and :data:`WRAPPED_IDS`.

    >>> print(registered_ids_table().splitlines()[2])  # doctest: +ELLIPSIS
    | `DSS14-v0` | track | speed drawn from 30, 40, 50, 60, 70 km/h, 8 directions (drawn) | 3000 (60 s) | ...
    """
    from dss14_env.envs.config import load_env_config

    defaults = load_env_config()
    dt = defaults.dt
    lines = ["| id | scenario | wind | `max_episode_steps` | for |", "|---|---|---|---|---|"]
    for p in PRESETS.values():
        kw = p.kwargs
        lines.append(f"| `{p.env_id}` | {kw.get('scenario', defaults.scenario)} | {_wind(kw, defaults)} | "
                     f"{p.max_episode_steps} ({p.max_episode_steps * dt:g} s) | {p.purpose} |")
    for env_id, what in WRAPPED_IDS.items():
        lines.append(f"| `{env_id}` | of its base (`DSS14-Hold-v0` by default) | of its base | of its base "
                     f"| {what} |")
    return "\n".join(lines)


#: the ids are registered without gymnasium's passive checker (``gymnasium.make(...,
#: disable_env_checker=False)`` adds it): it checks only the first reset and step, which the
#: environments check on every call (and the tests run gymnasium's full ``check_env``), and
#: after a refused first reset it fails every later first step (gymnasium 1.x keeps no reset
#: data to compare the step with)
DISABLE_ENV_CHECKER = True


def register_preset(p: Preset) -> None:
    """Register one preset's id with Gymnasium (idempotent; builds nothing)."""
    from gymnasium.envs.registration import register, registry

    if p.env_id not in registry:
        register(id=p.env_id, entry_point=ENTRY_POINT, vector_entry_point=VECTOR_ENTRY_POINT,
                 max_episode_steps=p.max_episode_steps, kwargs=dict(p.kwargs),
                 disable_env_checker=DISABLE_ENV_CHECKER)


def register_presets() -> None:
    """Register every preset's id with Gymnasium (idempotent; builds nothing)."""
    for p in PRESETS.values():
        register_preset(p)
