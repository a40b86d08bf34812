"""Lead (plus notch) position-loop designs: the highest gain crossover a position loop reaches on
the rate loop at a phase margin and a peak sensitivity, with either encoder kind.

The report's conclusion ([R] Section V) is that the drive encoders limit the PI loop to 0.1 Hz
and that encoders close to the axes would allow 0.7-1.0 Hz.  Its PI gains are one design; this
module asks what a loop of the classic shape reaches on the same rate loop.  The controller of
one axis is

    C(s) = k (1 + w_i / s) (1 + s / w_z) / (1 + s / w_p) N(s),

a PI whose zero ``w_i`` sits a factor (:data:`PI_ZERO_RATIOS`) below the crossover ``w_c``, a
lead of phase ``phi`` centred on the crossover (``w_z = w_c sqrt(a)``, ``w_p = w_c / sqrt(a)``,
``a = (1 - sin phi) / (1 + sin phi)``), and no, one or two notches
``N(s) = (s^2 + 2 z_z w_n s + w_n^2) / (s^2 + 2 z_p w_n s + w_n^2)`` on the plant's most
prominent resonances (:func:`notch_options`); ``k`` puts ``|L(j w_c)| = 1``.  The loop is
broken at the axis's rate command, ``L = C G`` with ``G`` the rate loop's r -> measured angle
(as the reproduction's highest-gain PI rows break it), the other axis closed by its PI.  The
search runs over the grid of target crossovers, lead phases, PI-zero ratios and notch options
and keeps the design with the highest crossover whose loop has a phase margin of at least
``pm_min`` at its first gain crossover, a peak sensitivity ``max |1 / (1 + L)|`` of at most
``ms_max`` (on :data:`F_GRID`, to 40 Hz) and a stable closed loop (both axes; every pole left
of 0).  A grid search: what it finds is a lower bound on what the class reaches.

The frequency responses use the rate loop's state space (:func:`dss14_env.model.linsys.freqresp`);
the controllers are python-control transfer functions and the closed loop is built with
``control.feedback``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import control as ct
import numpy as np

from dss14_env.model.linsys import freqresp

#: frequency grid of the loop-gain analysis, Hz (above the el gearbox resonance at 20 Hz)
F_GRID = np.geomspace(0.005, 40.0, 1600)
#: the grid a candidate is checked on again before it is kept: 4x finer and to 60 Hz (a lightly
#: damped resonance can peak between the search grid's points)
F_CHECK = np.geomspace(0.005, 60.0, 8000)
#: target crossovers searched, Hz
CROSSOVERS_HZ = np.geomspace(0.05, 2.5, 64)
#: lead phases searched, deg (0: a PI alone)
LEAD_PHASES_DEG = (0.0, 30.0, 45.0, 55.0, 65.0)
#: crossover / PI-zero ratios searched
PI_ZERO_RATIOS = (4.0, 12.0)
#: damping of the notches' zeros
NOTCH_ZERO_ZETA = 0.05
#: dampings of the notches' poles searched (the notch's width)
NOTCH_POLE_ZETAS = (0.3, 0.7)
#: the plant's resonances a notch may sit on: the most prominent this many between
#: :data:`NOTCH_BAND_HZ` (peaks of ``|s G|``), one notch or two
NOTCH_PEAKS = 3
NOTCH_BAND_HZ = (0.3, 10.0)


@dataclass(frozen=True)
class LeadDesign:
    """A lead (plus notch) position-loop controller of one axis and the margins it reaches.

    :param axis: ``"az"`` or ``"el"``
    :param encoders: ``"drive"`` or ``"axis"`` (what the loop measures)
    :param crossover_hz: first gain crossover of ``L``
    :param phase_margin_deg: phase margin there
    :param peak_sensitivity: ``max |1 / (1 + L)|`` over :data:`F_GRID`
    :param lead_phase_deg: the lead's phase ``phi``
    :param pi_zero_ratio: crossover / PI zero
    :param notches: ``(frequency Hz, pole damping)`` of each notch (empty: none)
    :param controller: ``C(s)`` (python-control transfer function, rad/s per rad)
    """

    axis: str
    encoders: str
    crossover_hz: float
    phase_margin_deg: float
    peak_sensitivity: float
    lead_phase_deg: float
    pi_zero_ratio: float
    notches: tuple[tuple[float, float], ...]
    controller: ct.TransferFunction


def _factors(fc_hz, phase_deg: float, pi_ratio: float, s):
    """PI and lead factors of ``C`` at ``s`` (arrays broadcast over ``fc_hz``)."""
    wc = 2 * np.pi * fc_hz
    c = 1 + (wc / pi_ratio) / s
    if phase_deg > 0:
        sphi = math.sin(math.radians(phase_deg))
        a = (1 - sphi) / (1 + sphi)
        c = c * (1 + s / (wc * math.sqrt(a))) / (1 + s / (wc / math.sqrt(a)))
    return c


def _notch(f_hz: float, zeta_p: float, s):
    wn = 2 * math.pi * f_hz
    return (s ** 2 + 2 * NOTCH_ZERO_ZETA * wn * s + wn ** 2) / (s ** 2 + 2 * zeta_p * wn * s + wn ** 2)


def lead_tf(fc_hz: float, phase_deg: float, pi_ratio: float,
            notches: tuple[tuple[float, float], ...] = ()) -> ct.TransferFunction:
    """``C(s)`` of the module docstring with ``k = 1``."""
    s = ct.tf("s")
    c = _factors(fc_hz, phase_deg, pi_ratio, s)
    for fn, zp in notches:
        c = c * _notch(fn, zp, s)
    return c


def _margins(L: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of ``L``: first gain crossover (Hz), phase margin (deg; NaN where ``|L|`` does not
    fall through 1 on the grid) and peak sensitivity (the rule of
    :func:`dss14_env.model.analysis.loop_margins`, vectorised).
    """
    mag = np.abs(L)
    below = mag < 1.0
    k = np.argmax(below, axis=1)
    ok = below.any(axis=1) & (k > 0)
    k = np.where(ok, k, 1)
    rows = np.arange(L.shape[0])
    ph = np.unwrap(np.angle(L), axis=1)
    ph -= 2 * np.pi * np.ceil(ph[:, :1] / (2 * np.pi))
    a, b = np.log(mag[rows, k - 1]), np.log(mag[rows, k])
    w = a / (a - b)
    fc = np.exp(np.log(f[k - 1]) + w * np.log(f[k] / f[k - 1]))
    pm = 180.0 + np.degrees(ph[rows, k - 1] + w * (ph[rows, k] - ph[rows, k - 1]))
    ms = np.max(1.0 / np.abs(1.0 + L), axis=1)
    return np.where(ok, fc, np.nan), np.where(ok, pm, np.nan), ms


def notch_options(g: np.ndarray, f: np.ndarray) -> list[tuple[tuple[float, float], ...]]:
    """No notch, one or two notches on the plant's most prominent resonances (module constants)."""
    import scipy.signal

    band = (f >= NOTCH_BAND_HZ[0]) & (f <= NOTCH_BAND_HZ[1])
    db = 20 * np.log10(np.abs(g * 2j * np.pi * f))
    idx, props = scipy.signal.find_peaks(np.where(band, db, -np.inf), prominence=1.0)
    top = [float(f[i]) for i in idx[np.argsort(-props["prominences"])][:NOTCH_PEAKS]]
    out: list[tuple[tuple[float, float], ...]] = [()]
    for n in (1, 2):
        for peaks in itertools.combinations(top, n):
            for zp in NOTCH_POLE_ZETAS:
                out.append(tuple((p, zp) for p in peaks))
    return out


def _closed_loop_abscissa(plant: ct.StateSpace, controllers: list[ct.TransferFunction]) -> float:
    """Largest pole real part (1/s) of ``plant`` (2 rate commands -> 2 measured angles) under
    ``u_i = C_i (c_i - y_i)``.
    """
    ctrl = ct.append(*(ct.tf2ss(c) for c in controllers))
    cl = ct.feedback(ct.series(ctrl, plant), np.eye(2))
    return float(np.max(np.linalg.eigvals(cl.A).real))


def lead_design(rate_loop: ct.StateSpace, axis: str, outputs: tuple[str, str], scale: tuple[float, float],
                other_pi: tuple[float, float], encoders: str = "drive", pm_min: float = 45.0,
                ms_max: float = 2.0) -> LeadDesign | None:
    """The lead (plus notch) design of one axis with the highest crossover (module docstring).

    :param rate_loop: the rate loop (inputs ``r_a``, ``r_e``)
    :param axis: ``"az"`` or ``"el"``
    :param outputs: the rate-loop outputs the two axes measure (az, el)
    :param scale: factors on those outputs (the measured angle per output unit)
    :param other_pi: ``(kp, ki)`` of the other axis's PI
    :param encoders: label of the encoder kind, kept in the result
    :param pm_min: least phase margin, deg
    :param ms_max: largest peak sensitivity
    :return: the design, or None when no candidate of the grid meets the criteria
    """
    k = ("az", "el").index(axis)
    inputs = ("r_a", "r_e")
    f = F_GRID
    s = 2j * np.pi * f
    g = freqresp(rate_loop, f, outputs[k], inputs[k]) * scale[k]
    fcs = CROSSOVERS_HZ[:, None]
    at = [np.argmin(np.abs(np.log(f / x))) for x in CROSSOVERS_HZ]
    candidates = []
    for notches in notch_options(g, f):
        n = np.ones_like(s)
        for fn, zp in notches:
            n = n * _notch(fn, zp, s)
        for phi, ratio in itertools.product(LEAD_PHASES_DEG, PI_ZERO_RATIOS):
            L = _factors(fcs, phi, ratio, s[None, :]) * (n * g)[None, :]
            gain = 1.0 / np.abs(L[np.arange(len(at)), at])
            fcx, pm, ms = _margins(L * gain[:, None], f)
            good = np.flatnonzero((pm >= pm_min) & (ms <= ms_max))
            candidates += [(fcx[i], pm[i], ms[i], CROSSOVERS_HZ[i], phi, ratio, notches, gain[i])
                           for i in good]
    rows = [rate_loop.output_labels.index(o) for o in outputs]
    cols = [rate_loop.input_labels.index(i) for i in inputs]
    plant = ct.ss(rate_loop.A, rate_loop.B[:, cols], np.diag(scale) @ rate_loop.C[rows], np.zeros((2, 2)))
    other = ct.tf([other_pi[0], other_pi[1]], [1.0, 0.0])
    sc = 2j * np.pi * F_CHECK
    gc = freqresp(rate_loop, F_CHECK, outputs[k], inputs[k]) * scale[k]
    for fcx, pm, ms, fc, phi, ratio, notches, gain in sorted(candidates, key=lambda x: -x[0]):
        n = np.ones_like(sc)
        for fn, zp in notches:
            n = n * _notch(fn, zp, sc)
        fcx, pm, ms = (float(x[0]) for x in _margins((gain * _factors(fc, phi, ratio, sc) * n * gc)[None, :],
                                                      F_CHECK))
        if not (pm >= pm_min and ms <= ms_max):
            continue  # met the criteria on the search grid only
        c = gain * lead_tf(fc, phi, ratio, notches)
        if _closed_loop_abscissa(plant, [c, other] if k == 0 else [other, c]) < 0.0:
            return LeadDesign(axis, encoders, float(fcx), float(pm), float(ms), float(phi), float(ratio),
                              tuple(notches), c)
    return None
