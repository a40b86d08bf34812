"""The report's PI position controller ([R] Eqs. 57-58) acting through ``DSS14-v0``.

Per axis, on the measured servo error ``e`` (axis rad, from observation entries 0-1)::

    r(t) = kp e(t) + ki int e dt                       (continuous, [R] Eq. 58)
    I[k] = I[k-1] + dt (e[k] + e[k-1]) / 2             (trapezoidal integral over one period)
    r[k] = kp e[k] + ki I[k]                           (held over [t_k, t_k+1) by the env)

and the action is ``r[k] / action_scale`` (clipped to [-1, 1]).  The first call after
:meth:`PIController.reset` starts bumplessly: ``I`` is set so that ``r`` equals the previous
applied rate command the environment reports (observation 10-11), i.e. the controller takes
over the antenna in the steady motion the episode starts in.  No anti-windup (the report's
loop is linear).  Gain sets come from ``configs/model.yaml`` (``kp1``: kp 1 1/s, ki 0.3 1/s^2;
``kp0.7``: kp 0.7, ki 0.2).

The controller accepts one observation ``(12,)`` or a batch ``(N, 12)`` (vector env); for a
batch, :meth:`PIController.restart` re-initialises the sub-environments that were reset.

:func:`sampled_three_sigma_mdeg` gives the exact stationary 3-sigma servo error of this
sampled PI on the env's discretised plant in wind (discrete Lyapunov equation), the
counterpart of :func:`dss14_env.wind.loads.three_sigma_mdeg` for the continuous PI loop.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import linalg

from dss14_env.baselines.base import Controller

DEG = math.pi / 180.0
MDEG = math.pi / 180.0e3


def gain_set(name: str) -> tuple[np.ndarray, np.ndarray]:
    """``(kp, ki)`` per axis ``[az, el]`` of a gain set of ``configs/model.yaml``.

    :raises ValueError: naming the unknown set
    """
    from dss14_env.model.config import load_model_config

    sets = load_model_config().gain_sets
    if name not in sets:
        raise ValueError(f"unknown gain set {name!r}; known: {sorted(sets)}")
    g = sets[name]
    return np.array([g.kp, g.kp], float), np.array([g.ki, g.ki], float)


def _env_config(env_or_config: Any) -> Any:
    cfg = getattr(getattr(env_or_config, "unwrapped", env_or_config), "config", None)
    if cfg is None and hasattr(env_or_config, "dt") and hasattr(env_or_config, "action_scale_deg_s"):
        cfg = env_or_config
    if cfg is None:
        raise TypeError(f"{env_or_config!r} is neither a DSS14 environment nor its EnvConfig")
    return cfg


class PIController(Controller):
    """The report's PI (Eqs. 57-58), discretised for the environment's period.

    :param env: a DSS14 environment (single or vector, wrapped or not) or its
        :class:`~dss14_env.envs.scenarios.EnvConfig`: supplies ``dt``, the action scale, the rate
        limit and the observation's error scale
    :param gains: a gain-set name of ``configs/model.yaml`` (default ``"kp1"``) or ``(kp, ki)``
        (scalars or per-axis pairs, 1/s and 1/s^2)
    :param bumpless: start from the observed previous rate command (default True); False
        starts the integrator at zero
    :param name: label, default ``"PI <gains>"``
    """

    def __init__(self, env: Any, gains: str | tuple = "kp1", *, bumpless: bool = True,
                 name: str | None = None) -> None:
        if isinstance(gains, str):
            kp, ki = gain_set(gains)
            label = gains
        else:
            kp, ki = (np.broadcast_to(np.asarray(g, float), (2,)).copy() for g in gains)
            label = f"kp {kp.tolist()}, ki {ki.tolist()}"
        if not (np.all(np.isfinite(kp)) and np.all(np.isfinite(ki)) and np.all(ki > 0)):
            raise ValueError(f"PI gains must be finite with ki > 0, got kp {kp}, ki {ki}")
        super().__init__(name or f"PI {label}")
        cfg = _env_config(env)
        self.kp, self.ki = kp, ki
        self.dt = float(cfg.dt)
        self.bumpless = bool(bumpless)
        self._err = cfg.error_scale_mdeg * MDEG  # observation unit of the error, rad
        self._rl = cfg.rate_limit_deg_s * DEG
        self._inv_scale = 1.0 / (cfg.action_scale_deg_s * DEG)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """Forget the integrators; the next :meth:`act` starts a new episode.

        :param seed: unused (the controller is deterministic)
        """
        super().reset(seed)
        self._I: np.ndarray | None = None
        self._e_prev: np.ndarray | None = None
        self._fresh: np.ndarray | None = None

    def restart(self, mask: np.ndarray) -> None:
        """Batched use: re-initialise the rows ``mask`` (sub-environments just reset) at the
        next :meth:`act`."""
        if self._fresh is not None:
            self._fresh |= np.asarray(mask, bool)

    def integral_action(self) -> np.ndarray:
        """The integral part ``ki * I`` of the last command, in action units (zeros before the
        first :meth:`act`)."""
        if self._I is None:
            return np.zeros(2)
        return self.ki * self._I * self._inv_scale

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Action(s) for one observation ``(12,)`` or a batch ``(N, 12)``.

        :raises ValueError: on a wrong observation shape
        """
        obs = np.asarray(observation, dtype=np.float64)
        if obs.shape[-1:] != (12,) or obs.ndim > 2:
            raise ValueError(f"observation must have shape (12,) or (N, 12), got {obs.shape}")
        e = obs[..., 0:2] * self._err
        if self._I is None or self._I.shape != e.shape:
            self._I = np.zeros_like(e)
            self._e_prev = e.copy()
            self._fresh = np.ones(e.shape[:-1], bool)
        else:
            self._I += 0.5 * self.dt * (e + self._e_prev)
        if np.any(self._fresh):
            f = self._fresh
            r_prev = obs[..., 10:12][f] * self._rl if self.bumpless else 0.0
            self._I[f] = (r_prev - self.kp * e[f]) / self.ki
            self._e_prev[f] = e[f]
            self._fresh[...] = False
        r = self.kp * e + self.ki * self._I
        self._e_prev = e
        self.info = {"rate_command_rad_s": r}
        return np.clip(r * self._inv_scale, -1.0, 1.0).astype(np.float32)


# ---------------------------------------------------------------------------- exact analysis
def sampled_loop(plant: Any, kappa: np.ndarray, kp: np.ndarray, ki: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sampled PI loop of :class:`PIController` on a discretised plant (hold, linear).

    No quantisation, no limiter, command fixed: ``e[k] = -theta[k]``.  State
    ``s[k] = [x[k], I[k-1], e[k-1]]``; ``s[k+1] = Phi s[k] + W xi[k]``.

    :param plant: a :class:`dss14_env.envs.plant.Plant`
    :param kappa: wind-direction factors (:meth:`dss14_env.envs.plant.Plant.kappa`)
    :param kp: proportional gains ``[az, el]``, 1/s
    :param ki: integral gains ``[az, el]``, 1/s^2
    :return: ``(Phi, W, C_e)`` with ``e[k] = C_e s[k]``
    """
    n, dt = plant.n, plant.dt
    Ce = -plant.C[:2]
    Kp, Ki = np.diag(kp), np.diag(ki)
    B = plant.Bd_r
    Phi = np.zeros((n + 4, n + 4))
    Phi[:n, :n] = plant.Ad + B @ (Kp + 0.5 * dt * Ki) @ Ce
    Phi[:n, n:n + 2] = B @ Ki
    Phi[:n, n + 2:] = 0.5 * dt * B @ Ki
    Phi[n:n + 2, :n] = 0.5 * dt * Ce
    Phi[n:n + 2, n:n + 2] = np.eye(2)
    Phi[n:n + 2, n + 2:] = 0.5 * dt * np.eye(2)
    Phi[n + 2:, :n] = Ce
    W = np.zeros((n + 4, plant.noise_rank))
    W[:n] = plant.noise_matrix(np.asarray(kappa, float))
    return Phi, W, np.hstack([Ce, np.zeros((2, 4))])


def sampled_three_sigma_mdeg(plant: Any, direction: float, gains: str | tuple = "kp1") -> np.ndarray:
    """Exact stationary 3-sigma servo errors ``[az, el]`` (mdeg) of the sampled PI in wind.

    Solves ``S = Phi S Phi^T + W W^T`` for :func:`sampled_loop`; the mean wind torque only
    shifts the mean, which the integral action removes.

    :param plant: a :class:`dss14_env.envs.plant.Plant` (its ``dt`` and wind speed)
    :param direction: wind direction relative to the dish, rad
    :param gains: gain-set name or ``(kp, ki)``
    :raises ValueError: if the sampled loop is unstable
    """
    if isinstance(gains, str):
        kp, ki = gain_set(gains)
    else:
        kp, ki = (np.broadcast_to(np.asarray(g, float), (2,)) for g in gains)
    Phi, W, Ce = sampled_loop(plant, plant.kappa(direction), kp, ki)
    rho = float(np.max(np.abs(np.linalg.eigvals(Phi))))
    if rho >= 1.0:
        raise ValueError(f"the sampled PI loop is unstable (spectral radius {rho:.6f})")
    S = linalg.solve_discrete_lyapunov(Phi, W @ W.T)
    return 3.0 * np.sqrt(np.diag(Ce @ S @ Ce.T)) * (180.0e3 / math.pi)
