"""The named environment presets: one table behind the registered Gymnasium ids and the
benchmark's scenarios.

Each preset is a set of environment keys (on top of ``configs/env.yaml``), the episode length
of its registered id and the warm-up that statistics leave out.  ``import dss14_env`` registers
every preset's id (:func:`register_presets`; nothing is built); the benchmark's scenarios
(:data:`dss14_env.bench.runner.SCENARIOS`) are the same presets by name.

>>> PRESETS["hold_front"].env_id, dict(PRESETS["hold_front"].kwargs)["wind_direction"]
('DSS14-HoldFront-v0', 'front')
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

#: wind directions of the random-direction presets, deg (0 = front)
EIGHT_DIRECTIONS = tuple(45.0 * i for i in range(8))


@dataclass(frozen=True)
class Preset:
    """One named environment configuration.

    :param env_id: the registered Gymnasium id
    :param kwargs: environment keys (``configs/env.yaml`` names) on top of the defaults
    :param max_episode_steps: truncation of the registered id, control periods (50 per second)
    :param warmup_s: seconds at the start that error statistics leave out
    :param description: one line for tables and docs
    """

    env_id: str
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    max_episode_steps: int = 3000
    warmup_s: float = 0.0
    description: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "kwargs", MappingProxyType(dict(self.kwargs)))


#: the presets by name
PRESETS: Mapping[str, Preset] = MappingProxyType({
    "track": Preset("DSS14-v0", {"scenario": "track", "wind_speed_kmh": "random",
                                 "wind_speed_grid_kmh": [30.0, 40.0, 50.0, 60.0, 70.0],
                                 "wind_direction": "random",
                                 "wind_direction_grid_deg": list(EIGHT_DIRECTIONS)},
                    3000, 5.0, "slow track, random 30-70 km/h wind and direction"),
    "hold": Preset("DSS14-Hold-v0", {"scenario": "hold", "wind_speed_kmh": 50.0,
                                     "wind_direction": "random",
                                     "wind_direction_grid_deg": [0.0, 90.0]},
                   3000, 5.0, "hold, 50 km/h front or side wind (drawn per episode)"),
    "hold_front": Preset("DSS14-HoldFront-v0", {"scenario": "hold", "wind_speed_kmh": 50.0,
                                                "wind_direction": "front"},
                         3000, 5.0, "hold, 50 km/h front wind (Table 4)"),
    "hold_side": Preset("DSS14-HoldSide-v0", {"scenario": "hold", "wind_speed_kmh": 50.0,
                                              "wind_direction": "side"},
                        3000, 5.0, "hold, 50 km/h side wind (Table 4)"),
    "step": Preset("DSS14-Step-v0", {"scenario": "step", "step_deg": 0.1, "step_axes": "both",
                                     "wind_speed_kmh": 0.0},
                   2000, 0.0, "0.1 deg step on both axes at 1 s, no wind (Fig. 21)"),
    "slew": Preset("DSS14-Slew-v0", {"scenario": "slew", "slew_deg": 5.0, "wind_speed_kmh": 30.0,
                                     "wind_direction": "random",
                                     "wind_direction_grid_deg": list(EIGHT_DIRECTIONS)},
                   3000, 0.0, "5 deg slew on both axes, 30 km/h wind"),
})

ENTRY_POINT = "dss14_env.envs.env:DSS14Env"
VECTOR_ENTRY_POINT = "dss14_env.envs.vector:DSS14VectorEnv"


def register_presets() -> None:
    """Register every preset's id with Gymnasium (idempotent; builds nothing)."""
    from gymnasium.envs.registration import register, registry

    for p in PRESETS.values():
        if p.env_id not in registry:
            register(id=p.env_id, entry_point=ENTRY_POINT, vector_entry_point=VECTOR_ENTRY_POINT,
                     max_episode_steps=p.max_episode_steps, kwargs=dict(p.kwargs))
