"""How smooth a controller's command is: the two measures every bench episode reports.

* **acceleration-limit hits** (:func:`limit_hit_pct`): the share of an episode's control
  periods in which the environment's limiter clipped the change of the rate command (its
  acceleration limit), in % of the periods run.  A controller that leaves the smoothing to
  the limiter sits on it.
* **command change above 5 Hz** (:func:`high_frequency_share`): per axis, the share of the
  variance of the first difference of the applied rate command that lies above
  :data:`CUTOFF_HZ`, from its Welch power spectral density (``scipy.signal.welch``, Hann
  window, segments of :data:`SEGMENT` samples or the whole signal when shorter, the mean
  removed): ``sum(P[f > 5 Hz]) / sum(P)``.  White noise gives the share of a flat spectrum
  above 5 Hz, ``(f_s / 2 - 5) / (f_s / 2)``: 0.8 at the 50-Hz control rate; a command that
  changes slowly gives about 0.

Both are computed over the whole episode (every command the drive received), and both pool
over episodes as means (:mod:`dss14_env.bench.statistics`).

>>> rng = np.random.default_rng(0)
>>> round(high_frequency_share(np.cumsum(rng.normal(size=20000)), 0.02), 1)  # white change
0.8
>>> t = np.arange(3000) * 0.02
>>> high_frequency_share(np.sin(2 * np.pi * 0.2 * t), 0.02) < 0.01  # a slow sine
True
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

#: the frequency above which the command's change counts as high-frequency, Hz
CUTOFF_HZ = 5.0
#: Welch segment length, samples (5.12 s at 50 Hz: 0.2-Hz resolution)
SEGMENT = 256
#: the fewest samples of the change a share is estimated from (NaN below)
MIN_SAMPLES = 16


def high_frequency_share(command: np.ndarray, dt: float, cutoff_hz: float = CUTOFF_HZ) -> float:
    """The share (0..1) of the variance of ``diff(command)`` above ``cutoff_hz`` (see the module
    docstring); NaN when the change has fewer than :data:`MIN_SAMPLES` samples or no variance.
    A command of several axes, shape ``(n, k)``, gives one share pooled over its axes: the
    axes' spectral densities are summed before the share is taken.

    :param command: the applied rate command, one sample per control period: one axis ``(n,)``
        or several ``(n, k)``
    :param dt: control period, s
    :param cutoff_hz: the boundary, Hz (below the Nyquist frequency ``1 / (2 dt)``)
    """
    if not 0.0 < cutoff_hz < 0.5 / dt:
        raise ValueError(f"cutoff_hz: between 0 and the Nyquist frequency {0.5 / dt:g} Hz, got {cutoff_hz!r}")
    c = np.asarray(command, float)
    if c.ndim not in (1, 2):
        raise ValueError(f"command: one axis (n,) or several (n, k), got shape {c.shape}")
    d = np.diff(c if c.ndim == 2 else c[:, None], axis=0)
    if len(d) < MIN_SAMPLES:
        return math.nan
    f, p = signal.welch(d, fs=1.0 / dt, nperseg=min(SEGMENT, len(d)), detrend="constant", axis=0)
    p = p.sum(axis=1)
    total = float(p.sum())
    if not total > 0.0:
        return math.nan
    return float(p[f > cutoff_hz].sum()) / total


def limit_hit_pct(hits: np.ndarray) -> float:
    """The share of control periods with a limiter hit, % (NaN for an empty episode).

    :param hits: one flag per control period
    """
    h = np.asarray(hits, bool)
    return 100.0 * float(h.mean()) if h.size else math.nan


__all__ = ["CUTOFF_HZ", "MIN_SAMPLES", "SEGMENT", "high_frequency_share", "limit_hit_pct"]
