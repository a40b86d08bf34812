"""Analysis helpers: step responses (exact ZOH), step metrics, bandwidths, peaks, margins.

>>> import control as ct
>>> from dss14_env.model.linsys import ss
>>> g = ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], ["u"], ["y"])
>>> t, y = step(g, "u", ["y"], 10.0, 1001)
>>> round(float(y[-1, 0]), 4)
1.0
"""

from __future__ import annotations

from typing import Sequence

import control as ct
import numpy as np
import scipy.linalg

from dss14_env.model.linsys import freqresp


def step(sys: ct.StateSpace, inp: str, outputs: Sequence[str], t_end: float, n: int
         ) -> tuple[np.ndarray, np.ndarray]:
    """Unit-step response from ``inp`` to ``outputs`` on ``n`` equally spaced samples.

    Exact for a step input: the state transition over one sample is the matrix exponential of
    the augmented matrix ``[[A, b], [0, 0]]`` (zero-order hold), so no integration error.
    """
    A = sys.A
    nx = A.shape[0]
    b = sys.B[:, sys.input_labels.index(inp)]
    oi = [sys.output_labels.index(o) for o in outputs]
    C, d = sys.C[oi], sys.D[oi, sys.input_labels.index(inp)]
    t = np.linspace(0.0, t_end, n)
    dt = t[1] - t[0]
    aug = np.zeros((nx + 1, nx + 1))
    aug[:nx, :nx], aug[:nx, nx] = A, b
    E = scipy.linalg.expm(aug * dt)
    Ad, bd = E[:nx, :nx], E[:nx, nx]
    x = np.zeros(nx)
    y = np.empty((n, len(oi)))
    for k in range(n):
        y[k] = C @ x + d
        x = Ad @ x + bd
    return t, y


def step_metrics(t: np.ndarray, y: np.ndarray, final: float = 1.0) -> dict:
    """Overshoot (%), 2 % and 5 % settling times (s), 10-90 % rise time (s) of a step response."""
    os_pct = max(0.0, (np.max(y) - final) / final * 100.0)
    out = {"overshoot_pct": float(os_pct)}
    for tag, band in (("settling_2pct_s", 0.02), ("settling_5pct_s", 0.05)):
        outside = np.flatnonzero(np.abs(y - final) > band * abs(final))
        out[tag] = float(t[min(outside[-1] + 1, t.size - 1)]) if outside.size else 0.0
    rise = [t[np.argmax(y >= lvl * final)] for lvl in (0.1, 0.9)]
    out["rise_s"] = float(rise[1] - rise[0])
    return out


def bandwidth_hz(sys: ct.StateSpace, out: str, inp: str, f_lo: float = 1e-3, f_hi: float = 10.0,
                 n: int = 2000) -> float:
    """First frequency (Hz) where |H| falls 3 dB below its DC value."""
    f = np.geomspace(f_lo, f_hi, n)
    mag = np.abs(freqresp(sys, f, out, inp))
    below = np.flatnonzero(mag < mag[0] * 10 ** (-3 / 20))
    if not below.size:
        return float("inf")
    k = below[0]
    # log-linear interpolation between the bracketing samples
    lvl = np.log(mag[0] * 10 ** (-3 / 20))
    a, b = np.log(mag[k - 1]), np.log(mag[k])
    return float(np.exp(np.log(f[k - 1]) + (lvl - a) / (b - a) * np.log(f[k] / f[k - 1])))


def peak_frequencies(f: np.ndarray, mag: np.ndarray, min_prominence_db: float = 3.0) -> np.ndarray:
    """Frequencies of local maxima of ``mag`` that stand ``min_prominence_db`` above the
    neighbouring minima (``scipy.signal.find_peaks`` on the dB curve)."""
    import scipy.signal
    idx, _ = scipy.signal.find_peaks(20 * np.log10(mag), prominence=min_prominence_db)
    return f[idx]


def loop_crossover_hz(loop_gain: np.ndarray, f: np.ndarray) -> float:
    """First frequency where |L| drops below 1 (gain crossover)."""
    k = np.flatnonzero(np.abs(loop_gain) < 1.0)
    return float(f[k[0]]) if k.size else float("inf")


def spectral_abscissa(sys: ct.StateSpace) -> float:
    """Largest real part of the poles (negative: asymptotically stable)."""
    return float(np.max(np.linalg.eigvals(sys.A).real))
