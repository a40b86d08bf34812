"""Residual reinforcement learning on top of the report's PI loop (``DSS14-Residual-v0``).

The learned policy does not replace the PI controller of [R] Eqs. 57-58; it adds a small
correction to its rate command (residual policy learning, Johannink et al. 2019, Silver et al.
2018)::

    a[k] = a_PI[k] + residual_scale * u[k],        u[k] in [-1, 1]^2 from the policy

with ``a_PI`` the action of :class:`dss14_env.baselines.pi.PIController` (the report's gains,
default ``kp1``: kp 1 1/s, ki 0.3 1/s^2) and ``a`` clipped to the environment's [-1, 1].  At
``u = 0`` the closed loop is exactly the report's, so training starts from a stable, sensible
controller and the policy only has to learn what PI leaves on the table (wind rejection).  The
policy sees the environment's 12 observations, the PI's integral term ``ki * I`` (in units of
the action scale, 2 entries) and, with ``history`` H > 0, the H previous measured servo errors
and applied rate commands (observation entries 0, 1, 10, 11 of the H steps before, newest
first; 4 H entries): the quantised encoder makes the one-step error rate mostly quantisation
noise, and a short history lets the network filter it (frame stacking).

This is the ``base="pi", action="residual"`` case of :mod:`dss14_env.agents.interface`; the
names here keep the residual vocabulary:

* :class:`ResidualPI` -- the composition for one environment (observe, combine);
* :class:`ResidualPIWrapper` / :func:`make_residual_env` -- the Gymnasium face, the entry point
  of ``DSS14-Residual-v0``;
* :class:`dss14_env.agents.policy.PolicyController` of a residual run -- what the runner scores;
  it sees the plain 12 observations like every other controller.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from dss14_env.agents.envs import DEFAULT_BASE_ID, make_wrapped_env
from dss14_env.agents.interface import HISTORY_ENTRIES, InterfaceSpec, InterfaceWrapper, PolicyInterface

#: the registered residual environment
RESIDUAL_ENV_ID = "DSS14-Residual-v0"
#: defaults of the residual composition: PI gain set, action units per unit of policy output,
#: previous steps in the observation
DEFAULT_GAINS = "kp1"
DEFAULT_RESIDUAL_SCALE = 0.05
DEFAULT_HISTORY = 0
#: keys of ``make_residual_env`` that are not keyword arguments of the base environment
RESIDUAL_KEYS = ("base_id", "gains", "residual_scale", "history", "history_entries")


def _env_config(env: Any) -> Any:
    return getattr(getattr(env, "unwrapped", env), "config", env)


class ResidualPI:
    """PI action plus a scaled residual for one environment (:class:`PolicyInterface`, N = 1).

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
        spec = InterfaceSpec(base="pi", action="residual", gains=gains,
                             residual_scale=residual_scale, history=history)
        self.interface = PolicyInterface(spec, _env_config(env), 1)
        self.obs_dim = self.interface.obs_dim

    @property
    def pi(self) -> Any:
        """The PI controller underneath."""
        return self.interface.pi

    @property
    def pi_action(self) -> np.ndarray:
        """The PI's action at the last observed step."""
        return self.interface.base_action[0].astype(np.float32)

    def reset(self) -> None:
        """Start a new episode (the PI starts bumplessly at the next :meth:`observe`)."""
        self.interface.reset()

    def observe(self, observation: np.ndarray) -> np.ndarray:
        """Advance the PI on the environment's observation; return the policy's observation
        ``(14 + 4 history,)`` (see the module doc).
        """
        return self.interface.observe(np.asarray(observation, np.float32)[None])[0]

    def combine(self, residual: np.ndarray) -> np.ndarray:
        """Environment action for the policy's residual at the last observed step.

        :raises ValueError: for a residual that is not finite or not of shape ``(2,)``
        """
        u = np.asarray(residual, np.float64)
        if u.shape != (2,) or not np.all(np.isfinite(u)):
            raise ValueError(f"residual action must be 2 finite numbers, got {residual!r}")
        return self.interface.action(u[None])[0]


class ResidualPIWrapper(InterfaceWrapper):
    """A DSS14 environment driven by ``PI + residual_scale * action`` (see the module doc).

    :param env: a DSS14 environment (``gymnasium.make("DSS14-Hold-v0")`` etc.)
    :param gains: PI gain set, default ``"kp1"``
    :param residual_scale: see :class:`ResidualPI`, default 0.05
    :param history: see :class:`ResidualPI`, default 0
    """

    def __init__(self, env: gym.Env, gains: str | tuple = DEFAULT_GAINS,
                 residual_scale: float = DEFAULT_RESIDUAL_SCALE,
                 history: int = DEFAULT_HISTORY) -> None:
        super().__init__(env, InterfaceSpec(base="pi", action="residual", gains=gains,
                                            residual_scale=residual_scale, history=history,
                                            history_entries=HISTORY_ENTRIES))


def make_residual_env(base_id: str = DEFAULT_BASE_ID, **kwargs: Any) -> InterfaceWrapper:
    """The entry point of ``DSS14-Residual-v0``: the base environment through the residual
    interface.

    :param base_id: the DSS14 environment underneath, default ``"DSS14-Hold-v0"``
    :param kwargs: ``gains``, ``residual_scale``, ``history``, ``history_entries`` and keyword
        arguments of ``gymnasium.make(base_id, ...)`` (e.g. ``max_episode_steps``,
        ``wind_speed_kmh``)
    """
    return make_wrapped_env(RESIDUAL_ENV_ID, base_id, **kwargs)


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
