"""Controllers that use the monopulse sensor (``sensors: [encoders, monopulse]``,
:mod:`dss14_env.envs.monopulse`): observation entries 12-13 are the measured pointing error
``[el, xel]``.

:class:`PIMonopulseController` (``pi_monopulse``) is the DSN's arrangement (Gawronski & Gudim,
TMO PR 42-137, 1999): the position loop on the encoders, and a slow monopulse loop around it
that moves the position loop's command until the beam's measured pointing error is zero.  Per
axis, with ``m`` the measured pointing error (rad) and ``S = [[0, 1], [cos E, 0]]`` the
pointing of a rigid rotation by the encoder angles ``[az, el]``::

    delta[k] = delta[k-1] + k_m dt S^-1 clip(m[k])  (the outer loop: an integrator)
    e'[k]    = e[k] + delta[k]                      (the position loop's error, [R] Eqs. 57-58)

so the PI drives the encoders to ``c + delta``, which in steady state puts the beam, not the
drives, on the command: the static deflection of the mean wind torque, which the encoders
cannot see, is taken out.  ``k_m`` (1/s) sets the outer loop's crossover, below the position
loop's (about ``kp`` rad/s).  The first step of an episode starts the PI bumplessly with
``delta = 0``; the integrand is clipped to the LQG's anti-windup clip (``integral_clip``,
2 mdeg), so that a commanded move, whose pointing error the position loop answers, does not
wind the outer loop up.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from dss14_env.baselines.design import PointingConfig, default_controllers_config, rigid_pointing
from dss14_env.baselines.lqg import LQGController
from dss14_env.baselines.mpc import MPCController
from dss14_env.baselines.pi import PIController, env_config
from dss14_env.baselines.yardstick import PointingYardstickController
from dss14_env.core.units import KMH, MDEG
from dss14_env.envs.core import OBS, OBS_SIZE
from dss14_env.envs.monopulse import MonopulseConstants

#: the observation's monopulse entries (el, xel), after the encoders' 12
MONOPULSE = slice(OBS_SIZE, OBS_SIZE + 2)


def xel_scale_of(env: Any) -> float:
    """``cos(E)`` of the structure model's elevation, of the model the environment runs on (the
    shipped one for a configuration alone).
    """
    plants = getattr(getattr(env, "unwrapped", env), "plants", None)
    if plants is not None:
        return float(plants.xel_scale)
    from dss14_env.model.config import load_model_config
    return math.cos(load_model_config().structure.elevation_angle)


def check_monopulse(env: Any, who: str) -> None:
    """That the environment has the monopulse sensor.

    :raises ValueError: one line naming ``who`` and the missing sensor
    """
    if "monopulse" not in getattr(env_config(env), "sensors", ()):
        raise ValueError(f"{who} needs the monopulse sensor: make the environment with "
                         "sensors=['encoders', 'monopulse']")


def pointing_to_axes(m: np.ndarray, xel_scale: float) -> np.ndarray:
    """Pointing errors ``(n, 2)`` ``[el, xel]`` as the encoder angles ``[az, el]`` that move the
    beam by them (``S^-1``: az = xel / cos E, el = el).
    """
    out = np.empty_like(m)
    out[:, 0] = m[:, 1] / xel_scale
    out[:, 1] = m[:, 0]
    return out


class PIMonopulseController(PIController):
    """The report's PI on the encoders with the DSN's monopulse outer loop (module docstring).

    :param env: a DSS14 environment with the monopulse sensor (or its configuration)
    :param gains: the PI's gain set (default ``"kp1"``) or ``(kp, ki)``
    :param outer_gain: the outer loop's integral gain ``k_m``, 1/s (default: section
        ``monopulse`` of ``configs/controllers.yaml``, 0.1)
    :param name: label, default ``"PI <gains> + monopulse"``
    :raises ValueError: without the monopulse sensor, or a non-positive ``outer_gain``
    """

    def __init__(self, env: Any, gains: str | tuple = "kp1", outer_gain: float | None = None,
                 name: str | None = None) -> None:
        check_monopulse(env, "pi_monopulse")
        if outer_gain is None:
            outer_gain = default_controllers_config().monopulse.outer_gain
        if not (math.isfinite(outer_gain) and outer_gain > 0):
            raise ValueError(f"outer_gain must be a positive number (1/s), got {outer_gain!r}")
        label = gains if isinstance(gains, str) else "custom gains"
        self.outer_gain = float(outer_gain)
        self.xel_scale = xel_scale_of(env)
        self.clip = default_controllers_config().lqg.integral_clip
        super().__init__(env, gains, name=name or f"PI {label} + monopulse")

    def _allocate(self, n: int) -> None:
        super()._allocate(n)
        self._delta = np.zeros((n, 2))

    def _step(self, obs: np.ndarray) -> np.ndarray:
        if obs.shape[1] <= MONOPULSE.start:
            raise ValueError(f"observation must have the monopulse entries ({MONOPULSE.stop} entries), "
                             f"got {obs.shape[1]}")
        f = self._fresh
        self._delta[f] = 0.0
        m = np.clip(obs[:, MONOPULSE] * self.error_unit, -self.clip, self.clip)
        go = ~f
        self._delta[go] += (self.outer_gain * self.dt) * pointing_to_axes(m[go], self.xel_scale)
        shifted = obs.copy()
        shifted[:, OBS.error] += self._delta / self.error_unit
        return super()._step(shifted)

    @property
    def offset_mdeg(self) -> np.ndarray:
        """The outer loop's command offset ``delta`` ``[az, el]``, mdeg (rows)."""
        return self._delta / MDEG


def monopulse_noise(env: Any) -> float:
    """The monopulse measurement's noise std per step as the designs take it, rad: the loop's
    input std ``sigma_w`` (:class:`dss14_env.envs.monopulse.MonopulseConstants`), floored at the
    LQG's extra measurement noise (``measurement_noise`` of section ``lqg``), so that a
    noiseless sensor keeps the Kalman problem regular.
    """
    k = MonopulseConstants.from_config(env_config(env))
    return math.hypot(k.sigma_w * MDEG, default_controllers_config().lqg.measurement_noise)


class MonopulseMeasurement:
    """The monopulse measurement of the pointing for an estimator controller (a mixin of
    :class:`dss14_env.baselines.lqg.EstimatorController` subclasses): ``S c - m``, the command's
    pointing less the measured pointing error, appended to the encoder readings.

    With the sensor updated every step, the loop's filter is inverted,
    ``m_w[k] = (m[k] - a m[k-1]) / (1 - a)``: that is the true pointing error plus white noise of
    std ``sigma_w`` exactly (no lag), the measurement the designs assume; the first step of an
    episode takes ``m`` itself.  With a longer update period the held output is taken as it is.
    Latency is not modelled.
    """

    def _monopulse_setup(self, env: Any, xel_scale: float) -> None:
        k = MonopulseConstants.from_config(env_config(env))
        self._pole = k.a if k.n_update == 1 else 0.0
        self._S = rigid_pointing(xel_scale)

    def _allocate(self, n: int) -> None:
        super()._allocate(n)  # type: ignore[misc]
        self._m_prev = np.zeros((n, 2))

    def measurement(self, obs: np.ndarray, y: np.ndarray, c: np.ndarray) -> np.ndarray:
        if obs.shape[1] <= MONOPULSE.start:
            raise ValueError(f"observation must have the monopulse entries ({MONOPULSE.stop} entries), "
                             f"got {obs.shape[1]}")
        m = obs[:, MONOPULSE] * self.interface.error_scale  # type: ignore[attr-defined]
        a = self._pole
        prev = np.where(self._fresh[:, None], m, self._m_prev)  # type: ignore[attr-defined]
        self._m_prev = m
        white = (m - a * prev) / (1.0 - a) if a else m
        return np.hstack([y, c @ self._S.T - white])


class MonopulseLQGController(MonopulseMeasurement, LQGController):
    """The pointing LQG whose Kalman filter fuses the encoders and the monopulse sensor
    (``lqg_monopulse``).

    Everything as :class:`dss14_env.baselines.lqg.PointingLQGController` (pointing design, wind
    inference, shaper, conditioning) except the estimator and the integrator: the filter
    measures, besides the drive encoders, the dish's pointing (:class:`MonopulseMeasurement`)
    as ``Cp x + F d`` -- the model's pointing plus the static deflection of the mean-torque
    state -- with the noise of :func:`monopulse_noise`, and the integrator sums the measured
    pointing error, so the beam, not the model's prediction of it, is held on the command.

    :param env: a DSS14 environment with the monopulse sensor (or its configuration)
    :param name: label, default ``"LQG-monopulse"``
    :param pointing: the pointing design's settings, default section ``pointing`` with the
        weights of section ``monopulse`` of ``configs/controllers.yaml``
    :raises ValueError: without the monopulse sensor
    """

    def __init__(self, env: Any, name: str = "LQG-monopulse", pointing: PointingConfig | None = None) -> None:
        check_monopulse(env, "lqg_monopulse")
        self._monopulse_setup(env, xel_scale_of(env))
        super().__init__(env, name, None, pointing or monopulse_pointing_config(),
                         pointing_noise=monopulse_noise(env))


def monopulse_pointing_config() -> PointingConfig:
    """The pointing section of ``configs/controllers.yaml`` with the weights of section
    ``monopulse`` (the fused designs').
    """
    cc = default_controllers_config()
    mc = cc.monopulse
    return dataclasses.replace(cc.pointing, action_change_weight=mc.action_change_weight,
                               encoder_error_weight=mc.encoder_error_weight)


class MonopulseMPCController(MonopulseMeasurement, MPCController):
    """The pointing MPC on :class:`MonopulseLQGController`'s estimator and integrator
    (``mpc_monopulse``): the Kalman filter fuses the encoders and the monopulse measurement, the
    constrained problem (:class:`dss14_env.baselines.mpc.MPCController`, the pointing section's
    ``mpc_action_change_weight``) is the law, the fused LQG's law the fallback.  One episode at
    a time.

    :param env: a DSS14 environment with the monopulse sensor (or its configuration)
    :param name: label, default ``"MPC-monopulse"``
    :raises ValueError: without the monopulse sensor
    """

    def __init__(self, env: Any, name: str = "MPC-monopulse") -> None:
        check_monopulse(env, "mpc_monopulse")
        self._monopulse_setup(env, xel_scale_of(env))
        super().__init__(env, name, None, None, True, monopulse_pointing_config(),
                         pointing_noise=monopulse_noise(env))


class MonopulseYardstickController(MonopulseMeasurement, PointingYardstickController):
    """The pointing yardstick that also measures the pointing with the monopulse sensor
    (``yardstick_monopulse``): the full-order H2-optimal LQG for ``J_point`` and the episode's
    wind (an oracle, :class:`dss14_env.baselines.yardstick.YardstickController`), its Kalman
    filter fusing the drive encoders and the monopulse measurement (:class:`MonopulseMeasurement`,
    noise :func:`monopulse_noise`).  Its analytic figures:
    :func:`dss14_env.baselines.yardstick.expected_performance` with ``pointing_noise``.

    :param env: a DSS14 environment with the monopulse sensor (or its configuration)
    :param name: label, default ``"yardstick_monopulse"``
    :raises ValueError: without the monopulse sensor
    """

    def __init__(self, env: Any, wind_speed: float = 50 * KMH, direction: str | float = "front",
                 name: str = "yardstick_monopulse") -> None:
        check_monopulse(env, "yardstick_monopulse")
        self._monopulse_setup(env, xel_scale_of(env))
        super().__init__(env, wind_speed, direction, name, pointing_noise=monopulse_noise(env))
