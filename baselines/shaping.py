"""Feasible references for the model-based controllers: command shaper and reference model.

A command that the limits cannot follow (a step, the start of a slew) handed to a high-gain
LQG saturates the command limiter and makes it limit-cycle; the DSN's LQG servos therefore
run a command preprocessor (W. Gawronski, "Command preprocessor for the DSN LQG controllers",
ASME Design Engineering Technical Conferences, DETC99, 1999).  :class:`CommandShaper` is such a
preprocessor; :class:`ReferenceGenerator` drives a noise-free copy of the design model along
the shaped command, so the controller regulates the deviation from a motion the plant can
follow within the limits.  Both work on rows (one episode per row, arrays ``(n, 2)``).

>>> from dss14_env.core.units import DEG
>>> shaper = CommandShaper(0.16 * DEG, 0.03 * DEG, 0.02)
>>> shaper.reset(1)
>>> _ = shaper(np.zeros((1, 2)), np.zeros((1, 2)))                 # the episode starts at rest
>>> c_s, v_s, a_s = shaper(np.array([[0.1 * DEG, 0.0]]), np.zeros((1, 2)))   # a 0.1 deg az step
>>> float(c_s[0, 0]), round(float(a_s[0, 0] / DEG), 3)            # closed at 0.03 deg/s^2
(0.0, 0.03)
"""

from __future__ import annotations

import math

import numpy as np

from dss14_env.baselines.base import check_mask
from dss14_env.baselines.design import DesignModel

#: default fraction of the limiter's limits the reference model's feedforward may use
FEEDFORWARD_MARGIN = 0.9


class CommandShaper:
    """Command preprocessor: a rate- and acceleration-limited copy of the command, per row.

    The shaped command ``(c_s, v_s)`` moves with a piecewise-constant acceleration ``acc_s``
    (held over each period, so ``c_s`` is exactly a parabola between steps) chosen each step from
    the raw command ``(c, v)``: the raw command's own acceleration passes through, a gap (a step)
    is closed with at most ``accel``, the total is capped at ``accel_max``::

        p      = c - c_s                                  (gap)
        k      = sqrt(1/4 + 2 |p| / (a dt^2)) - 1/2       (steps needed to brake over p)
        v_des  = clip(v + sign(p) min(a dt k, |p| / dt), -v_max, v_max)
        dv_raw = v - v_prev                               (raw command's change)
        acc_s  = clip(dv_raw + clip(v_des - v_s - dv_raw, -a dt, a dt), -a_max dt, a_max dt) / dt

    A command that respects the limits is passed through (``p = 0``, ``v_s = v``).  At a row's
    first call the shaped command starts on the raw one (rate clipped to ``rate``).

    :param rate: largest shaped rate (encoder rad/s)
    :param accel: largest acceleration used to close a gap (rad/s^2)
    :param dt: period, s
    :param accel_max: largest shaped acceleration in all (rad/s^2), default ``accel``
    """

    def __init__(self, rate: float, accel: float, dt: float, accel_max: float | None = None) -> None:
        accel_max = accel if accel_max is None else accel_max
        for name, v in (("rate", rate), ("accel", accel), ("dt", dt), ("accel_max", accel_max)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"shaper {name} must be positive and finite, got {v!r}")
        self.rate, self.accel, self.dt = float(rate), float(accel), float(dt)
        self.accel_max = max(float(accel_max), self.accel)
        self.reset(1)

    def reset(self, n: int = 1) -> None:
        """Forget the shaped commands; ``n`` rows start on their raw command at the next call."""
        self.n = int(n)
        self.c = np.zeros((n, 2))
        self.v = np.zeros((n, 2))
        self.acc = np.zeros((n, 2))
        self.v_raw = np.zeros((n, 2))
        self.fresh = np.ones(n, bool)

    def restart(self, mask: np.ndarray) -> None:
        """The rows ``mask`` start over on their raw command at the next call."""
        self.fresh |= check_mask(mask, self.n)

    def __call__(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Shaped ``(c_s, v_s, acc_s)`` (each ``(n, 2)``) for the raw commands ``(c, v)`` of this
        step (rad, rad/s; rad/s^2); ``acc_s`` is held over the coming period.
        """
        c, v = np.asarray(c, float), np.asarray(v, float)
        if c.shape != (self.n, 2) or v.shape != (self.n, 2):
            raise ValueError(f"shaper input must have shape ({self.n}, 2), got {c.shape} and {v.shape}")
        a, dt = self.accel, self.dt
        f, go = self.fresh, ~self.fresh
        self.c[go] = self.c[go] + self.v[go] * dt + 0.5 * self.acc[go] * dt * dt
        self.v[go] = self.v[go] + self.acc[go] * dt
        self.c[f], self.v[f], self.v_raw[f] = c[f], np.clip(v[f], -self.rate, self.rate), v[f]
        self.fresh[:] = False
        p = c - self.c
        ap = np.abs(p)
        k = np.sqrt(0.25 + 2.0 * ap / (a * dt * dt)) - 0.5
        v_des = np.clip(v + np.sign(p) * np.minimum(a * dt * k, ap / dt), -self.rate, self.rate)
        dv_raw = v - self.v_raw
        self.v_raw = v.copy()
        am = self.accel_max * dt
        self.acc = np.clip(dv_raw + np.clip(v_des - self.v - dv_raw, -a * dt, a * dt), -am, am) / dt
        return self.c.copy(), self.v.copy(), self.acc.copy()


class ReferenceGenerator:
    """Reference model: a noise-free copy of the design model driven along the shaped command.

    The model is driven by the quasi-steady feedforward of the shaped parabola and a gentle
    state feedback ``K_ref`` (the controllers use a position pull, ``K_ref = [k_pos I, 0]``)::

        x_qs, r_qs = reference_state(c_s, v_s, accel_ff * acc_s)
        r_ff       = r_qs - K_ref [x_ref - x_qs; r_ff_prev - r_qs]    (limited to margin x limits)
        x_ref(k+1) = Ad x_ref(k) + Bd r_ff(k)

    The controller then regulates the deviation from ``(x_ref, r_ff)``, which the plant can
    follow within the limits, so the feedback does not saturate on a step or a slew.  A command
    the limits can follow (hold, track) passes through: the ramp feedforward is exact for the
    model, ``x_ref = x_qs``.  The rate loop settles in 3-5 s (its lag compensator and the az
    anti-resonance), so a shaped step of a few mdeg/s^2 is what it follows without overshoot.
    The rows' states are the caller's: :meth:`start` gives the first, :meth:`advance` the next.

    :param dm: design model (its wind states stay at zero)
    :param K_ref: state feedback of the reference model on ``[x; r_prev]`` (2 x (n + 2))
    :param rate_limit: command limiter's rate limit, rad/s
    :param rate_step: command limiter's largest change per period, rad/s
    :param margin: fraction of the rate limit the feedforward may use
    :param accel_ff: share of the shaped acceleration in the feedforward (0: ramp only)
    :param accel_margin: fraction of the acceleration limit (``rate_step``) the feedforward may
        use, default ``margin``; the rest is left to the controller's feedback
    """

    def __init__(self, dm: DesignModel, K_ref: np.ndarray, rate_limit: float, rate_step: float,
                 margin: float = FEEDFORWARD_MARGIN, accel_ff: float = 0.0,
                 accel_margin: float | None = None) -> None:
        if K_ref.shape != (2, dm.n + 2):
            raise ValueError(f"K_ref must be 2 x {dm.n + 2}, got {K_ref.shape}")
        accel_margin = margin if accel_margin is None else accel_margin
        for name, v in (("margin", margin), ("accel_margin", accel_margin)):
            if not 0.0 < v <= 1.0:
                raise ValueError(f"reference {name} must be in (0, 1], got {v!r}")
        self.dm = dm
        self.accel_ff = float(accel_ff)
        self.K = K_ref
        self.rate_limit, self.rate_step = float(rate_limit), float(rate_step)
        self.margin, self.accel_margin = float(margin), float(accel_margin)
        z2 = np.zeros(2)
        n = dm.n
        self.Xv, self.Xa = np.zeros((n, 2)), np.zeros((n, 2))
        self.Rv, self.Ra = np.zeros((2, 2)), np.zeros((2, 2))
        for i, e in enumerate(np.eye(2)):
            self.Xv[:, i], self.Rv[:, i] = dm.reference_state(z2, e)
            self.Xa[:, i], self.Ra[:, i] = dm.reference_state(z2, z2, e)

    def quasi_steady(self, c: np.ndarray, v: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States ``(k, n)`` and commands ``(k, 2)`` of the model on the parabolas ``(c, v, a)``."""
        x = v @ self.Xv.T + a @ self.Xa.T
        x[:, :2] += c
        return x, v @ self.Rv.T + a @ self.Ra.T

    def _feedforward(self, x: np.ndarray, r: np.ndarray, x_qs: np.ndarray, r_qs: np.ndarray) -> np.ndarray:
        r_des = r_qs - np.concatenate([x - x_qs, r - r_qs], axis=1) @ self.K.T
        step, lim = self.accel_margin * self.rate_step, self.margin * self.rate_limit
        return np.clip(np.clip(r_des, r - step, r + step), -lim, lim)

    def start(self, c_s: np.ndarray, v_s: np.ndarray, a_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(x_ref, r_ff)`` of the rows' first period: the model on the shaped command."""
        x, r = self.quasi_steady(c_s, v_s, self.accel_ff * a_s)
        return x, self._feedforward(x, r, x, r)

    def advance(self, x: np.ndarray, r: np.ndarray, c_s: np.ndarray, v_s: np.ndarray, a_s: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """``(x_ref, r_ff)`` of the next period from the rows' last ``(x_ref, r_ff)``."""
        x = x @ self.dm.Ad.T + r @ self.dm.Bd.T
        x_qs, r_qs = self.quasi_steady(c_s, v_s, self.accel_ff * a_s)
        return x, self._feedforward(x, r, x_qs, r_qs)
