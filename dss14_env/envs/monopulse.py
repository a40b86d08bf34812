"""The monopulse sensor: the beam's own pointing error, measured against the spacecraft signal.

A monopulse feed forms a sum and a difference pattern per axis; their ratio gives the beam's
pointing error in elevation and cross-elevation (the DSN's Ka-band tracking: Gawronski & Gudim,
TMO PR 42-137, 1999; Gudim et al., TMO PR 42-138, 1999).  The receiver estimates the ratio in
a tracking loop of noise bandwidth ``B_L``; its output jitters with the carrier's
signal-to-noise ratio.  The sensor of the environments (``sensors: [encoders, monopulse]``)::

    h[k]   = p[k - d]                                      the true pointing error, d steps late
    f[k]   = a f[k-1] + (1 - a) (h[k] + sigma_w w[k])      at an update step (every n_u steps)
    f[k]   = f[k-1]                                        between updates (held)
    a      = exp(-4 B_L T_u),  T_u = n_u dt                first-order loop of noise bandwidth B_L
    sigma  = theta_3dB / (k_m sqrt(2 (C/N_0) / B_L))        the loop output's rms jitter
    sigma_w = sigma sqrt((1 + a) / (1 - a))                 so that f - (filtered p) has std sigma

``p = [el, xel]`` in mdeg is the dish's true pointing error (the info's ``pointing_error_*``),
``w[k]`` standard normals (two per step, the last two columns of the episode's noise block,
:func:`dss14_env.envs.scenarios.draw_noise_block`), ``theta_3dB`` the half-power beamwidth
of the band, ``k_m`` the normalised monopulse slope, ``C/N_0`` the carrier-to-noise density.
The tracking-error formula is the standard one of amplitude monopulse (Sherman & Barton,
"Monopulse Principles and Techniques", 2nd ed., Artech House 2011, ch. 12; for a continuous
carrier the pulse rate times the pulse SNR is ``C/N_0``).  At a reset the loop starts in its
stationary state about the true error: ``f[0] = p[0] + sigma w_0``, the delay line holds
``p[0]``.  ``monopulse_cnr_dbhz: null`` makes the sensor noiseless, ``monopulse_bandwidth_hz:
null`` removes the loop filter (``a = 0``): with both, and no latency, ``f = p`` exactly.

The functions take arrays of ``N`` rows; both environments step the sensor with the compiled
loop :func:`sensor_step` (the single one with N = 1), as they step the rest
(:mod:`dss14_env.envs.fused`).

>>> from dss14_env.envs.config import load_env_config
>>> k = MonopulseConstants.from_config(load_env_config(sensors=["encoders", "monopulse"]))
>>> round(k.sigma, 4), k.n_update, k.n_delay
(0.1148, 1, 0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from dss14_env.envs.config import EnvConfig, whole_steps
from dss14_env.envs.core import OBS_ERROR_BOUND, OBS_HIGH, OBS_SIZE

#: the observation entries the sensor adds (12, 13), in units of ``error_scale_mdeg``
OBS_NAMES = ("monopulse_el", "monopulse_xel")
#: the info keys the sensor adds (every step and reset): the measurement, mdeg (the true
#: pointing errors are ``pointing_error_el_mdeg`` and ``pointing_error_xel_mdeg``)
INFO_KEYS = ("monopulse_el_mdeg", "monopulse_xel_mdeg")

#: 0.1-dB beamwidths of the 70-m antenna, mdeg, per band (Gudim et al., TMO PR 42-138, 1999)
BEAMWIDTH_01DB_MDEG = {"S": 22.0, "X": 5.9, "Ka": 1.5}
#: ratio of the half-power to the 0.1-dB beamwidth of a Gaussian main beam: the loss at an
#: offset ``u`` is ``12 (u / theta_3dB)^2`` dB, so the 0.1-dB width is ``2 sqrt(0.1 / 12)``
#: ``theta_3dB`` (assumed beam shape)
HALF_POWER_PER_01DB = 1.0 / (2.0 * math.sqrt(0.1 / 12.0))


def half_power_beamwidth_mdeg(band: str) -> float:
    """The half-power beamwidth ``theta_3dB`` of a band, mdeg (:data:`HALF_POWER_PER_01DB`).

    >>> round(half_power_beamwidth_mdeg("Ka"), 2)
    8.22
    """
    return BEAMWIDTH_01DB_MDEG[band] * HALF_POWER_PER_01DB


def jitter_mdeg(cnr_dbhz: float | None, bandwidth_hz: float | None, band: str, slope: float,
                dt: float) -> float:
    """The tracking loop's rms output jitter ``sigma`` per axis, mdeg (the module's formula).

    :param cnr_dbhz: carrier-to-noise density ``C/N_0``, dB-Hz (None: noiseless, 0)
    :param bandwidth_hz: loop noise bandwidth ``B_L``, Hz (None: no loop filter; the noise
        bandwidth is then that of one sample per step, ``1 / (2 dt)``)
    :param band: ``"S"``, ``"X"`` or ``"Ka"``
    :param slope: normalised monopulse slope ``k_m``
    :param dt: control period, s
    """
    if cnr_dbhz is None:
        return 0.0
    b = bandwidth_hz if bandwidth_hz is not None else 0.5 / dt
    return half_power_beamwidth_mdeg(band) / (slope * math.sqrt(2.0 * 10.0 ** (cnr_dbhz / 10.0) / b))


@dataclass(frozen=True)
class MonopulseConstants:
    """The sensor's constants (:meth:`from_config`).

    :param sigma: stationary rms jitter of the loop output per axis, mdeg
    :param sigma_w: std of the noise per update entering the loop, mdeg
    :param a: the loop filter's pole per update
    :param n_update: steps per update
    :param n_delay: latency, steps
    """

    sigma: float
    sigma_w: float
    a: float
    n_update: int
    n_delay: int

    @classmethod
    def from_config(cls, c: EnvConfig) -> MonopulseConstants:
        """The constants of a checked configuration (with or without the sensor; its periods are
        whole numbers of steps, :meth:`dss14_env.envs.config.EnvConfig.checked`).
        """
        n_u, n_d = whole_steps(c.monopulse_update_s, c.dt, 1), whole_steps(c.monopulse_latency_s, c.dt, 0)
        b = c.monopulse_bandwidth_hz
        a = math.exp(-4.0 * b * n_u * c.dt) if b is not None else 0.0
        sigma = jitter_mdeg(c.monopulse_cnr_dbhz, b, c.monopulse_band, c.monopulse_slope, n_u * c.dt)
        return cls(sigma, sigma * math.sqrt((1.0 + a) / (1.0 - a)), a, n_u, n_d)


class MonopulseState(NamedTuple):
    """The sensor's state, one row per (sub-)environment."""

    #: true pointing errors of the last ``n_delay + 1`` steps, oldest first ``(N, d + 1, 2)``, mdeg
    history: np.ndarray
    #: the loop output ``[el, xel]`` ``(N, 2)``, mdeg: the measurement
    out: np.ndarray
    #: steps since the reset ``(N,)``
    k: np.ndarray


def sensor_reset(p0: np.ndarray, z0: np.ndarray, k: MonopulseConstants) -> MonopulseState:
    """The sensor's state at a reset.

    :param p0: true pointing errors ``(N, 2)`` ``[el, xel]`` at t = 0, mdeg
    :param z0: standard normals ``(N, 2)`` (:func:`dss14_env.envs.scenarios.draw_reset`)
    """
    hist = np.repeat(p0[:, None, :], k.n_delay + 1, axis=1)
    return MonopulseState(hist, p0 + k.sigma * z0, np.zeros(p0.shape[0], np.int64))


def observation_high(sensors: tuple[str, ...]) -> np.ndarray:
    """The observation's bounds: :data:`dss14_env.envs.core.OBS_HIGH`, then with the monopulse
    sensor its two entries' (:data:`OBS_NAMES`).
    """
    if "monopulse" not in sensors:
        return OBS_HIGH
    return np.concatenate((OBS_HIGH, np.full(2, OBS_ERROR_BOUND, np.float32)))


def sensor_constants(k: MonopulseConstants) -> np.ndarray:
    """:func:`sensor_step`'s constants ``[sigma_w, a, n_update]``."""
    return np.array([k.sigma_w, k.a, k.n_update])


@njit(nogil=True)
def sensor_observe(out: np.ndarray, inv_scale: float, obs: np.ndarray) -> None:
    """The observation's monopulse entries (12, 13) of every row: the measurement ``out``
    ``(N, 2)`` ``[el, xel]`` (mdeg) times ``inv_scale = 1 / error_scale_mdeg``, clamped to
    +-:data:`dss14_env.envs.core.OBS_ERROR_BOUND`, into ``obs`` ``(N, 14)`` float32.
    """
    b = OBS_ERROR_BOUND
    for i in range(out.shape[0]):
        for m in range(2):
            x = out[i, m] * inv_scale
            obs[i, OBS_SIZE + m] = b if x > b else (-b if x < -b else x)


@njit(nogil=True)
def sensor_step(history: np.ndarray, out: np.ndarray, steps: np.ndarray, p: np.ndarray, W: np.ndarray, j: int,
                mc: np.ndarray, inv_scale: float, obs: np.ndarray) -> None:
    """The sensor of every row after one step (the module's equations), in place, and its
    observation entries (:func:`sensor_observe`).

    :param history: :attr:`MonopulseState.history`, ``out`` and ``steps`` its other fields
    :param p: true pointing errors ``(2, N)`` ``[el, xel]`` at the step's end, mdeg
    :param W: standard normals ``(T, N, >= 2)``: this step's are the last two columns of ``W[j]``
    :param mc: :func:`sensor_constants`
    """
    sw, a, n_update = mc[0], mc[1], int(mc[2])
    b = 1.0 - a
    d = history.shape[1] - 1
    c = W.shape[2] - 2
    for i in range(out.shape[0]):
        for m in range(d):
            history[i, m, 0] = history[i, m + 1, 0]
            history[i, m, 1] = history[i, m + 1, 1]
        history[i, d, 0] = p[0, i]
        history[i, d, 1] = p[1, i]
        steps[i] += 1
        if n_update > 1 and steps[i] % n_update != 0:
            continue  # held between updates
        out[i, 0] = (history[i, 0, 0] + sw * W[j, i, c]) * b + a * out[i, 0]
        out[i, 1] = (history[i, 0, 1] + sw * W[j, i, c + 1]) * b + a * out[i, 1]
    sensor_observe(out, inv_scale, obs)
