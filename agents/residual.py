"""Residual reinforcement learning on top of the report's PI loop.

The learned policy does not replace the PI controller of [R] Eqs. 57-58; it adds a small
correction to its rate command (residual policy learning, Johannink et al. 2019, Silver et al.
2018)::

    a[k] = a_PI[k] + residual_scale * u[k],        u[k] in [-1, 1]^2 from the policy

with ``a_PI`` the action of :class:`dss14_env.baselines.pi.PIController` (the report's gains, default
``kp1``: kp 1 1/s, ki 0.3 1/s^2) and ``a`` clipped to the environment's [-1, 1].  At ``u = 0``
the closed loop is exactly the report's, so training starts from a stable, sensible controller
and the policy only has to learn what PI leaves on the table (wind rejection).  The policy sees
the environment's 12 observations, the PI's integral term ``ki * I`` (in units of the action
scale, 2 entries; controller state a memoryless network cannot rebuild) and, with ``history``
H > 0, the H previous measured servo errors and applied rate commands (observation entries 0, 1,
10, 11 of the H steps before, newest first; 4 H entries): the quantised encoder makes the
one-step error rate mostly quantisation noise, and a short history lets the network filter it
(frame stacking, as the field does for partially observed control).

Two faces of one :class:`ResidualPI` core, so training and scoring compose actions the same way:

* :class:`ResidualPIWrapper` (Gymnasium wrapper; id ``DSS14-Residual-v0`` registered when this
  module is imported, ``env_module: dss14_env.agents.residual`` in a PPO config) -- what PPO trains on;
* :class:`dss14_env.agents.policy.PPOController` of a residual run -- what the runner scores; it sees the
  plain 12 observations like every other controller.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from dss14_env.baselines.pi import PIController

#: extra observation entries: the PI integral term, action units; bound of the Box
INTEGRAL_BOUND = 1.0e3
#: the registered residual environment
RESIDUAL_ENV_ID = "DSS14-Residual-v0"
#: defaults of the residual composition: base environment, PI gain set, action units per unit
#: of policy output, previous steps in the observation
DEFAULT_BASE_ID = "DSS14-Hold-v0"
DEFAULT_GAINS = "kp1"
DEFAULT_RESIDUAL_SCALE = 0.05
DEFAULT_HISTORY = 0
#: keys of ``make_residual_env`` that are not keyword arguments of the base environment
RESIDUAL_KEYS = ("base_id", "gains", "residual_scale", "history")
#: environment observation entries kept in the history: servo errors, previous applied rates
HISTORY_ENTRIES = (0, 1, 10, 11)


class ResidualPI:
    """PI action plus a scaled residual: the composition shared by wrapper and controller.

    :param env: a DSS14 environment (or its EnvConfig) for the PI's period and scales
    :param gains: PI gain set of ``configs/model.yaml`` (default ``"kp1"``) or ``(kp, ki)``
    :param residual_scale: action units per unit of policy output, default 0.05 (0.0125 deg/s
        at the default 0.25 deg/s action scale: about 10x the PI's command in 50 km/h wind,
        far below the limits)
    :param history: previous steps in the observation (see the module doc), default 0
    :raises ValueError: for a residual scale that is not finite and positive, or a negative
        history
    """

    def __init__(self, env: Any, gains: str | tuple = DEFAULT_GAINS,
                 residual_scale: float = DEFAULT_RESIDUAL_SCALE,
                 history: int = DEFAULT_HISTORY) -> None:
        scale = float(residual_scale)
        if not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(f"residual_scale must be finite and > 0, got {residual_scale!r}")
        if isinstance(history, bool) or not isinstance(history, int) or history < 0:
            raise ValueError(f"history must be an integer >= 0, got {history!r}")
        self.pi = PIController(env, gains)
        self.residual_scale = scale
        self.history = history
        self.obs_dim = 14 + 4 * history
        self._pi_action = np.zeros(2, np.float32)
        self._past: np.ndarray | None = None

    def reset(self) -> None:
        """Start a new episode (the PI starts bumplessly at the next :meth:`observe`)."""
        self.pi.reset()
        self._past = None

    def observe(self, observation: np.ndarray) -> np.ndarray:
        """Advance the PI on the environment's observation; return the policy's observation.

        :param observation: the environment's observation ``(12,)``
        :return: ``(14 + 4 history,)``: the observation, the PI integral term ``ki * I`` /
            action scale, then the history (at an episode's first step: the first observation
            repeated, the steady state the episode starts in)
        """
        obs = np.asarray(observation, np.float32)
        self._pi_action = self.pi.act(obs)
        integral = self.pi.integral_action()
        parts = [obs, np.clip(integral, -INTEGRAL_BOUND, INTEGRAL_BOUND).astype(np.float32)]
        if self.history:
            now = obs[list(HISTORY_ENTRIES)]
            if self._past is None:
                self._past = np.tile(now, (self.history, 1))
            parts.append(self._past.ravel())
            self._past = np.roll(self._past, 1, axis=0)
            self._past[0] = now
        return np.concatenate(parts)

    def combine(self, residual: np.ndarray) -> np.ndarray:
        """Environment action for the policy's residual at the last observed step.

        :raises ValueError: for a residual that is not finite or not of shape ``(2,)``
        """
        u = np.asarray(residual, np.float64)
        if u.shape != (2,) or not np.all(np.isfinite(u)):
            raise ValueError(f"residual action must be 2 finite numbers, got {residual!r}")
        u = np.clip(u, -1.0, 1.0)
        return np.clip(self._pi_action + self.residual_scale * u, -1.0, 1.0).astype(np.float32)


class ResidualPIWrapper(gym.Wrapper):
    """A DSS14 environment driven by ``PI + residual_scale * action`` (see the module doc).

    Action: ``Box(-1, 1, (2,))`` residual; observation: ``Box((14 + 4 history,))`` (the
    environment's 12 entries, the PI integral term az, el in action units, the history).
    Reward, termination and info
    are the environment's (the reward's action-change term acts on the applied total action).

    :param env: a DSS14 environment (``gymnasium.make("DSS14-Hold-v0")`` etc.)
    :param gains: PI gain set, default ``"kp1"``
    :param residual_scale: see :class:`ResidualPI`, default 0.05
    :param history: see :class:`ResidualPI`, default 0
    """

    def __init__(self, env: gym.Env, gains: str | tuple = DEFAULT_GAINS,
                 residual_scale: float = DEFAULT_RESIDUAL_SCALE,
                 history: int = DEFAULT_HISTORY) -> None:
        super().__init__(env)
        self.core = ResidualPI(env, gains, residual_scale, history)
        high = env.observation_space.high
        integral = np.full(2, INTEGRAL_BOUND, np.float32)
        high = np.concatenate([high, integral, np.tile(high[list(HISTORY_ENTRIES)], history)])
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)

    def reset(self, *, seed: int | None = None,
              options: dict | None = None) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.core.reset()
        return self.core.observe(obs), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(self.core.combine(action))
        return self.core.observe(obs), reward, terminated, truncated, info


def make_residual_env(base_id: str = DEFAULT_BASE_ID, gains: str | tuple = DEFAULT_GAINS,
                      residual_scale: float = DEFAULT_RESIDUAL_SCALE,
                      history: int = DEFAULT_HISTORY, **env_kwargs: Any) -> ResidualPIWrapper:
    """``ResidualPIWrapper(gymnasium.make(base_id, **env_kwargs))``: the registered entry point.

    :param base_id: the DSS14 environment underneath, default ``"DSS14-Hold-v0"``
    :param gains: PI gain set, default ``"kp1"``
    :param residual_scale: see :class:`ResidualPI`, default 0.05
    :param history: see :class:`ResidualPI`, default 0
    :param env_kwargs: keyword arguments of ``gymnasium.make(base_id, ...)`` (e.g.
        ``max_episode_steps``, ``wind_speed_kmh``)
    """
    import dss14_env  # noqa: F401  (registers the base environments)

    return ResidualPIWrapper(gym.make(base_id, **env_kwargs), gains, residual_scale, history)


def base_env_args(env_kwargs: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """``(base_id, base env keyword arguments)`` of :func:`make_residual_env`'s keyword arguments.

    >>> base_env_args({"base_id": "DSS14-Step-v0", "history": 8, "wind_speed_kmh": 30.0})
    ('DSS14-Step-v0', {'wind_speed_kmh': 30.0})
    """
    kw = dict(env_kwargs)
    base = {k: v for k, v in kw.items() if k not in RESIDUAL_KEYS}
    return kw.get("base_id", DEFAULT_BASE_ID), base


__all__ = ["DEFAULT_BASE_ID", "DEFAULT_GAINS", "DEFAULT_HISTORY", "DEFAULT_RESIDUAL_SCALE",
           "RESIDUAL_ENV_ID", "RESIDUAL_KEYS", "ResidualPI", "ResidualPIWrapper", "base_env_args",
           "make_residual_env"]
