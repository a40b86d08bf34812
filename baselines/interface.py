"""What a model-based controller may know about the environment: its interface, not its plant.

:class:`ControlInterface` holds the control period, the action scale, the command limiter's
limits, the error scale, the reward's action-change weight and the encoder's resolution and
noise (the sensor specification), all SI; :class:`Weights` are the cost scales derived from it;
:class:`ObservationReader` decodes the ``DSS14-v0`` observation (layout in
:class:`dss14_env.envs.env.DSS14Env`) to SI.

>>> ci = ControlInterface.default()
>>> round(ci.dt, 3), round(ci.rate_limit / DEG, 3), round(ci.rate_step / DEG, 4)
(0.02, 0.25, 0.004)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from dss14_env.core.units import DEG, MDEG
from dss14_env.envs.config import load_env_config
from dss14_env.envs.core import OBS

#: relative margin inside the limiter's limits that a controller's own limits keep: the action
#: and the observed previous command are float32, the limiter checks in float64, so a command on
#: the limit itself can land a rounding error past it and be clipped
LIMIT_MARGIN = 1e-3


@dataclass(frozen=True)
class Weights:
    """Cost scales taken from the environment: error scale (rad), action scale (rad/s per unit
    action) and the reward's action-change weight.
    """

    error_scale: float
    action_scale: float
    action_change: float

    def __post_init__(self) -> None:
        for name in ("error_scale", "action_scale"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        if not (math.isfinite(self.action_change) and self.action_change >= 0):
            raise ValueError(f"action_change weight must be >= 0, got {self.action_change!r}")


@dataclass(frozen=True)
class ControlInterface:
    """The environment's interface as a controller sees it (all SI).

    Built from an environment (:meth:`from_env`), its configuration (:meth:`from_config`) or
    the shipped ``configs/env.yaml`` (:meth:`default`).
    """

    dt: float
    action_scale: float
    rate_limit: float
    accel_limit: float
    error_scale: float
    action_change_weight: float
    encoder_bits: int | None
    encoder_noise: float
    encoders: str = "drive"

    @classmethod
    def from_config(cls, cfg: Any) -> ControlInterface:
        """From a :class:`dss14_env.envs.config.EnvConfig` (or anything with its key names)."""
        return cls(float(cfg.dt), cfg.action_scale_deg_s * DEG, cfg.rate_limit_deg_s * DEG,
                   cfg.accel_limit_deg_s2 * DEG, cfg.error_scale_mdeg * MDEG,
                   float(cfg.action_change_weight), cfg.encoder_bits, cfg.encoder_noise_mdeg * MDEG,
                   str(getattr(cfg, "encoders", "drive")))

    @classmethod
    def from_env(cls, env: Any) -> ControlInterface:
        """From a ``DSS14Env`` or ``DSS14VectorEnv`` (wrapped or not).

        :raises TypeError: if ``env`` has no DSS14 configuration
        """
        cfg = getattr(getattr(env, "unwrapped", env), "config", None)
        if cfg is None:
            raise TypeError(f"{env!r} has no DSS14 configuration (.unwrapped.config)")
        return cls.from_config(cfg)

    @classmethod
    def default(cls, **overrides: Any) -> ControlInterface:
        """From the shipped ``configs/env.yaml`` (keys of it as overrides)."""
        return cls.from_config(load_env_config(**overrides))

    @property
    def weights(self) -> Weights:
        """The cost scales of the reward."""
        return Weights(self.error_scale, self.action_scale, self.action_change_weight)

    @property
    def rate_step(self) -> float:
        """Largest change of the rate command per period, rad/s."""
        return self.accel_limit * self.dt


def as_interface(env_or_interface: Any) -> ControlInterface:
    """A :class:`ControlInterface` from an environment, its config, an interface, or ``None``
    (the shipped defaults).
    """
    if env_or_interface is None:
        return ControlInterface.default()
    if isinstance(env_or_interface, ControlInterface):
        return env_or_interface
    if hasattr(env_or_interface, "unwrapped") or hasattr(env_or_interface, "config"):
        return ControlInterface.from_env(env_or_interface)
    return ControlInterface.from_config(env_or_interface)


class ObservationReader:
    """Decode ``DSS14-v0`` observations (rows of an ``(n, 12)`` array, checked) to SI.

    :meth:`read` returns ``(y, c, c_rate, r_prev)``, each ``(n, 2)``: encoder reading relative
    to the start (rad), command relative to the start (rad), command rate (rad/s), previous
    applied rate command (rad/s).
    """

    def __init__(self, interface: ControlInterface) -> None:
        self.interface = interface

    def read(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        rl = self.interface.rate_limit
        return (obs[:, OBS.encoder] * DEG, obs[:, OBS.command] * DEG, obs[:, OBS.command_rate] * rl,
                obs[:, OBS.prev_rate] * rl)
