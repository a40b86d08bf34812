"""Analysis helpers: step responses (exact ZOH), step metrics, bandwidths, peaks, margins,
exact DC gains and the poles of a channel.

>>> import control as ct
>>> from dss14_env.model.linsys import ss
>>> g = ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], ["u"], ["y"])
>>> t, y = step(g, "u", ["y"], 10.0, 1001)
>>> round(float(y[-1, 0]), 4)
1.0
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import control as ct
import numpy as np
import scipy.linalg

from dss14_env.model.linsys import balance, freqresp


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
    neighbouring minima (``scipy.signal.find_peaks`` on the dB curve).
    """
    import scipy.signal
    idx, _ = scipy.signal.find_peaks(20 * np.log10(mag), prominence=min_prominence_db)
    return f[idx]


def loop_crossover_hz(loop_gain: np.ndarray, f: np.ndarray) -> float:
    """First frequency where |L| drops below 1 (gain crossover), grid resolution."""
    k = np.flatnonzero(np.abs(loop_gain) < 1.0)
    return float(f[k[0]]) if k.size else float("inf")


def loop_margins(loop_gain: np.ndarray, f: np.ndarray) -> tuple[float, float]:
    """Gain crossover (Hz) and phase margin (deg) of a loop gain sampled on ascending ``f``.

    The crossover is the first frequency where ``|L|`` falls through 1, interpolated linearly
    in ``log|L|`` against ``log f``; the phase is unwrapped along ``f`` from its value at
    ``f[0]`` taken in (-360, 0] deg, interpolated at the crossover, and the margin is
    ``180 + phase``.

    :return: ``(crossover_hz, phase_margin_deg)``; ``(inf, nan)`` when ``|L|`` stays above 1.

    >>> f = np.geomspace(0.01, 10.0, 400)
    >>> s = 2j * np.pi * f
    >>> fc, pm = loop_margins(1.0 / (s * (1 + s)), f)  # integrator and a lag of 1 rad/s
    >>> round(fc, 3), round(pm, 1)  # |L| = 1 at w = 0.786 rad/s: 0.125 Hz, 51.8 deg
    (0.125, 51.8)
    """
    mag = np.abs(loop_gain)
    below = np.flatnonzero(mag < 1.0)
    if not below.size:
        return float("inf"), float("nan")
    k = int(below[0])
    if k == 0:
        return float(f[0]), float("nan")
    ph = np.unwrap(np.angle(loop_gain))
    ph -= 2 * np.pi * np.ceil(ph[0] / (2 * np.pi))  # ph[0] in (-2 pi, 0]
    a, b = np.log(mag[k - 1]), np.log(mag[k])
    w = a / (a - b)  # fraction of the step from f[k-1] to f[k] where log|L| = 0
    fc = float(np.exp(np.log(f[k - 1]) + w * np.log(f[k] / f[k - 1])))
    phase = ph[k - 1] + w * (ph[k] - ph[k - 1])
    return fc, float(180.0 + np.degrees(phase))


def peak_gain_db(sys: ct.StateSpace, out: str, inp: str, f_lo: float = 1e-3, f_hi: float = 10.0,
                 n: int = 4000) -> float:
    """Largest ``|H|`` over ``[f_lo, f_hi]`` (log grid of ``n`` points), in dB."""
    f = np.geomspace(f_lo, f_hi, n)
    return float(20.0 * np.log10(np.max(np.abs(freqresp(sys, f, out, inp)))))


def dc_gain(sys: ct.StateSpace, out: str, inp: str) -> float:
    """Exact DC gain of one channel by a linear solve, not by a low-frequency evaluation.

    States that feed no state (their column of ``A`` is zero) and are not seen by ``out`` --
    the rigid-body angles of the structure, which only integrate a rate -- are dropped first;
    the rest of ``A`` must then be non-singular.

    :raises ValueError: if the remaining ``A`` is singular (a free integrator in the channel)

    >>> from dss14_env.model.linsys import ss
    >>> g = ss([[-2.0, 0.0], [1.0, 0.0]], [[4.0], [0.0]], [[1.0, 0.0]], [[0.0]], ["u"], ["y"])
    >>> dc_gain(g, "y", "u")  # the second state integrates the first and is not observed
    2.0
    """
    oi, ii = sys.output_labels.index(out), sys.input_labels.index(inp)
    A, b, c = sys.A, sys.B[:, ii], sys.C[oi]
    keep = [k for k in range(A.shape[0]) if np.any(A[:, k] != 0.0) or c[k] != 0.0]
    Ak = A[np.ix_(keep, keep)]
    try:
        x = np.linalg.solve(Ak, -b[keep])
    except np.linalg.LinAlgError:
        raise ValueError(f"{inp} -> {out} has a free integrator: no finite DC gain") from None
    return float(c[keep] @ x + sys.D[oi, ii])


def channel_poles(sys: ct.StateSpace, channels: Mapping[str, tuple[str, str]],
                  f_max_hz: float = 1.0) -> list[dict]:
    """Poles below ``f_max_hz`` (natural frequency), each assigned to the channel it shows in.

    For each pole ``p`` the residue of every channel ``(out, inp)``,
    ``(c v)(w^H b) / (w^H v)`` with the right and left eigenvectors ``v``, ``w``, is computed
    on the balanced realisation (:func:`dss14_env.model.linsys.balance`); the pole goes to the
    channel with the largest ``|residue|``.  Poles at the origin (``|p|`` below 1e-9 of the
    largest) are left out: in the rate loop they are the rigid-body angles, which no rate
    channel sees.  Complex pairs are listed once.

    :param channels: ``{name: (output, input)}``
    :return: one dict per pole, ascending in frequency: ``channel``, ``freq_hz`` (|p| / 2 pi),
        ``zeta`` (-Re p / |p|), ``kind`` (``"real"`` or ``"pair"``), ``re`` and ``im``
        (1/s, rad/s) and ``dominance`` (largest |residue| over the next largest; ``inf`` for
        one channel)
    """
    il, ol = list(sys.input_labels), list(sys.output_labels)
    A, B, C, _ = balance(sys.A, sys.B, sys.C)
    lam, wl, vr = scipy.linalg.eig(A, left=True, right=True)
    scale = np.max(np.abs(lam))
    rows = []
    for k, p in enumerate(lam):
        if p.imag < 0 or abs(p) < 1e-9 * scale or abs(p) / (2 * np.pi) > f_max_hz:
            continue
        v, w = vr[:, k], wl[:, k].conj()
        den = w @ v
        res = {name: abs((C[ol.index(o)] @ v) * (w @ B[:, il.index(i)]) / den)
               for name, (o, i) in channels.items()}
        ranked = sorted(res.items(), key=lambda kv: -kv[1])
        dom = ranked[0][1] / ranked[1][1] if len(ranked) > 1 and ranked[1][1] > 0 else float("inf")
        rows.append({"channel": ranked[0][0], "freq_hz": float(abs(p) / (2 * np.pi)),
                     "zeta": float(-p.real / abs(p)),
                     "kind": "pair" if abs(p.imag) > 1e-9 * abs(p) else "real",
                     "re": float(p.real), "im": float(abs(p.imag)), "dominance": float(dom)})
    return sorted(rows, key=lambda r: r["freq_hz"])


def spectral_abscissa(sys: ct.StateSpace) -> float:
    """Largest real part of the poles (negative: asymptotically stable)."""
    return float(np.max(np.linalg.eigvals(sys.A).real))
