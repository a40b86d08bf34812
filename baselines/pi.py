"""The report's PI position controller ([R] Eqs. 57-58) acting through ``DSS14-v0``.

Per axis, on the measured servo error ``e`` (axis rad, from observation entries 0-1)::

    r(t) = kp e(t) + ki int e dt                       (continuous, [R] Eq. 58)
    I[k] = I[k-1] + dt (e[k] + e[k-1]) / 2             (trapezoidal integral over one period)
    r[k] = kp e[k] + ki I[k]                           (held over [t_k, t_k+1) by the env)

and the action is ``r[k] / action_scale`` (clipped to [-1, 1]).  The first call of an episode
starts bumplessly: ``I`` is set so that ``r`` equals the previous applied rate command the
environment reports (observation 10-11), i.e. the controller takes over the antenna in the
steady motion the episode starts in.  No anti-windup (the report's loop is linear).  Gain sets
come from the environment's own model (the shipped ``configs/model.yaml``: ``kp1``: kp 1 1/s,
ki 0.3 1/s^2; ``kp0.7``: kp 0.7, ki 0.2).

Batchable (:class:`dss14_env.baselines.base.Controller`): every row is an independent PI.  The
exact stationary analysis of this sampled PI is
:func:`dss14_env.baselines.analysis.sampled_three_sigma_mdeg`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from dss14_env.baselines.base import (
    Controller,
    check_batch_size,
    check_mask,
    check_observation,
    check_observations,
)
from dss14_env.core.units import DEG, MDEG
from dss14_env.envs.core import OBS
from dss14_env.model.config import load_model_config


def env_model(env: Any) -> Any:
    """The calibrated model an environment runs on (its plant factory's), or None (an
    :class:`~dss14_env.envs.config.EnvConfig`, or anything without one).
    """
    plants = getattr(getattr(env, "unwrapped", env), "plants", None)
    return getattr(plants, "model", None)


def gain_set(name: str, model: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """``(kp, ki)`` per axis ``[az, el]`` of a gain set of the model
    (:meth:`dss14_env.model.assembly.DSS14Model.gains`; None: the shipped ``configs/model.yaml``).

    :raises ValueError: naming the unknown set
    """
    sets = (load_model_config() if model is None else model.cfg).gain_sets
    if name not in sets:
        raise ValueError(f"unknown gain set {name!r}; known: {sorted(sets)}")
    if model is not None:
        kp, ki = model.gains(name)
        return np.array(kp, float), np.array(ki, float)
    g = sets[name]
    return np.array([g.kp, g.kp], float), np.array([g.ki, g.ki], float)


def gains_per_axis(gains: str | tuple, model: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """``(kp, ki)`` per axis from a gain-set name of ``model`` (None: the shipped one) or
    ``(kp, ki)`` (scalars or per-axis pairs).
    """
    if isinstance(gains, str):
        return gain_set(gains, model)
    kp, ki = (np.broadcast_to(np.asarray(g, float), (2,)).copy() for g in gains)
    return kp, ki


def env_config(env_or_config: Any) -> Any:
    """The :class:`~dss14_env.envs.config.EnvConfig` of an environment (single or vector,
    wrapped or not) or the config itself.

    :raises TypeError: for anything else
    """
    cfg = getattr(getattr(env_or_config, "unwrapped", env_or_config), "config", None)
    if cfg is None and hasattr(env_or_config, "dt") and hasattr(env_or_config, "action_scale_deg_s"):
        cfg = env_or_config
    if cfg is None:
        raise TypeError(f"{env_or_config!r} is neither a DSS14 environment nor its EnvConfig")
    return cfg


class PIController(Controller):
    """The report's PI (Eqs. 57-58), discretised for the environment's period.

    :param env: a DSS14 environment (single or vector, wrapped or not) or its
        :class:`~dss14_env.envs.config.EnvConfig`: supplies ``dt``, the action scale, the rate
        limit and the observation's error scale
    :param gains: a gain-set name of the environment's model (default ``"kp1"``; an
        :class:`~dss14_env.envs.config.EnvConfig` alone: of the shipped ``configs/model.yaml``)
        or ``(kp, ki)``
        (scalars or per-axis pairs, 1/s and 1/s^2)
    :param bumpless: start from the observed previous rate command (default True); False
        starts the integrator at zero
    :param name: label, default ``"PI <gains>"``
    """

    batchable = True

    def __init__(self, env: Any, gains: str | tuple = "kp1", *, bumpless: bool = True,
                 name: str | None = None) -> None:
        kp, ki = gains_per_axis(gains, env_model(env))
        label = gains if isinstance(gains, str) else f"kp {kp.tolist()}, ki {ki.tolist()}"
        if not (np.all(np.isfinite(kp)) and np.all(np.isfinite(ki)) and np.all(ki > 0)):
            raise ValueError(f"PI gains must be finite with ki > 0, got kp {kp}, ki {ki}")
        super().__init__(name or f"PI {label}")
        cfg = env_config(env)
        self.kp, self.ki = kp, ki
        self.dt = float(cfg.dt)
        self.bumpless = bool(bumpless)
        self.error_unit = cfg.error_scale_mdeg * MDEG  # observation unit of the error, rad
        self.rate_limit = cfg.rate_limit_deg_s * DEG
        self.action_scale = cfg.action_scale_deg_s * DEG
        self.reset()

    # ---------------------------------------------------------------- episodes
    def _allocate(self, n: int) -> None:
        self.n = n
        self._integral = np.zeros((n, 2))
        self._e_prev = np.zeros((n, 2))
        self._fresh = np.ones(n, bool)

    def reset(self, seed: int | None = None) -> None:
        """Forget the integrator; the next :meth:`act` starts a new episode.

        :param seed: unused (the controller is deterministic)
        """
        super().reset(seed)
        self._allocate(1)
        self._single = True

    def reset_batch(self, n: int, seeds: Sequence[int] | None = None) -> None:
        """Start ``n`` episodes (rows); ``seeds`` unused (the controller is deterministic)."""
        self._allocate(check_batch_size(n, seeds))
        self._single = False
        self.info_batch = {}

    def _implicit_batch(self, n: int) -> None:
        """A controller that has not stepped since its reset takes its number of rows from the
        first batched call (:meth:`act` with ``(N, 12)``, :meth:`restart` with ``(N,)``).
        """
        if n != self.n and self._fresh.all():
            self.reset_batch(n)

    def restart(self, mask: np.ndarray) -> None:
        """Re-initialise the rows ``mask`` (sub-environments just reset) at the next
        :meth:`act_batch`.
        """
        self._implicit_batch(int(np.size(mask)))
        self._fresh |= check_mask(mask, self.n)

    @property
    def _I(self) -> np.ndarray:
        """The integrator state ``I`` (rad s), shaped as :meth:`integral_action`
        (``tests/test_agents_residual.py`` reads it under this name).
        """
        return self._integral[0] if self._single else self._integral

    def integral_action(self) -> np.ndarray:
        """The integral part ``ki * I`` of the last command, in action units: ``(2,)`` after
        :meth:`act` with one observation (or :meth:`reset`), ``(n, 2)`` after a batch (or
        :meth:`reset_batch`); zeros before the first step.
        """
        out = self.ki * self._integral / self.action_scale
        return out[0] if self._single else out

    # ---------------------------------------------------------------- control
    def _step(self, obs: np.ndarray) -> np.ndarray:
        """One period for all rows; ``obs`` checked, float64 ``(n, 12)``."""
        e = obs[:, OBS.error] * self.error_unit
        f = self._fresh
        go = ~f
        self._integral[go] += 0.5 * self.dt * (e[go] + self._e_prev[go])
        if f.any():
            r_prev = obs[f, OBS.prev_rate] * self.rate_limit if self.bumpless else 0.0
            self._integral[f] = (r_prev - self.kp * e[f]) / self.ki
            self._fresh[:] = False
        r = self.kp * e + self.ki * self._integral
        self._e_prev = e
        self.info_batch = {"rate_command_rad_s": r}
        return np.clip(r / self.action_scale, -1.0, 1.0).astype(np.float32)

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Action ``(2,)`` for one observation ``(12,)``.

        An ``(N, 12)`` array is passed to :meth:`act_batch`, starting ``N`` episodes first if
        the controller has not stepped since its last reset (an implicit :meth:`reset_batch`).

        :raises ValueError: on a wrong-shape or non-finite observation
        """
        if np.ndim(observation) == 2:
            self._implicit_batch(np.shape(observation)[0])
            return self.act_batch(observation)
        obs = check_observation(observation)
        if self.n != 1:
            raise ValueError(f"act() runs one episode, but the controller runs a batch of {self.n}; "
                             "use act_batch or reset()")
        a = self._step(obs[None])[0]
        self._single = True
        self.info = {"rate_command_rad_s": self.info_batch["rate_command_rad_s"][0]}
        return a

    def act_batch(self, observations: np.ndarray) -> np.ndarray:
        """Actions ``(n, 2)`` for the rows' observations ``(n, 12)``.

        :raises ValueError: on a wrong shape or a non-finite entry
        """
        a = self._step(check_observations(observations, self.n))
        self._single = False
        return a
