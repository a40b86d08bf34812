"""Along-wind gust model for the DSS-14 70-m antenna: the Davenport spectrum.

The mean wind speed ``U`` is the 10-min mean at the reference height
(:data:`REFERENCE_HEIGHT_M`, 10 m); the gust ``u(t)`` is the zero-mean
fluctuation about it.  Everything is in SI: m/s, Hz, s; PSDs are
one-sided, in (m/s)^2/Hz, so that ``var(u) = integral_0^inf S(f) df``.

The module provides

* :func:`davenport_psd` and :func:`davenport_variance` -- the spectrum and its
  exact integral ``6 kappa U^2``; :func:`davenport_band_variance` -- the
  integral over a finite band (closed form);
* :func:`generate_gusts` -- a gust record by spectral (FFT) synthesis;
* :func:`davenport_filter` -- a continuous-time state-space shaping filter
  driven by unit white noise, built from one rational fit in normalised
  frequency (:func:`davenport_normalised_fit`) and scaled to any ``U``;
  :func:`filter_psd`, :func:`filter_variance` and
  :func:`davenport_filter_fit_error` check it;
* :func:`plot_gust_psd` -- a diagnostic plot.

Sources: A. G. Davenport, "The spectrum of horizontal gustiness near the
ground in high winds", Q. J. R. Meteorol. Soc. 87 (1961) 194-211;
E. Simiu and R. H. Scanlan, *Wind Effects on Structures*, Wiley, 1978.
See ``docs/wind.md``.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass
from typing import Union

import numpy as np
import numpy.typing as npt
from scipy import linalg, optimize, signal

from dss14_env.core.outdir import atomic_save_figure

__all__ = [
    "DAVENPORT_KAPPA",
    "DAVENPORT_LENGTH_M",
    "REFERENCE_HEIGHT_M",
    "FIT_X_LOW",
    "FIT_X_HIGH",
    "DEFAULT_FILTER_ORDER",
    "DavenportFit",
    "davenport_psd",
    "davenport_variance",
    "davenport_band_variance",
    "generate_gusts",
    "davenport_normalised_fit",
    "davenport_filter",
    "filter_psd",
    "filter_variance",
    "davenport_filter_fit_error",
    "plot_gust_psd",
]

ArrayLike = npt.ArrayLike
PathLike = Union[str, "os.PathLike[str]"]

#: Surface drag coefficient kappa (dimensionless), referred to the 10-m mean
#: speed.  0.005 is Davenport's (1961) value for open, unobstructed country
#: (kappa = [0.4 / ln(10 m / z0)]^2 gives z0 ~ 0.035 m); Simiu & Scanlan (1978).
DAVENPORT_KAPPA: float = 0.005

#: Davenport's length scale L in m: the spectrum depends on frequency through
#: x = L f / U (Davenport 1961; Simiu & Scanlan 1978).
DAVENPORT_LENGTH_M: float = 1200.0

#: Height in m at which the mean speed U of the Davenport spectrum is taken
#: (Davenport 1961).  The spectrum has no height dependence otherwise, so no
#: function needs this value; callers must pass the 10-m mean speed.
REFERENCE_HEIGHT_M: float = 10.0

#: Normalised-frequency band x = L f / U over which the shaping filter is fitted.
#: With the default L it covers 0.003-10 Hz for 4 m/s <= U <= 36 m/s.
FIT_X_LOW: float = 0.1
FIT_X_HIGH: float = 3000.0

#: Default number of poles of the shaping filter (it has one zero fewer).
DEFAULT_FILTER_ORDER: int = 4

_MAX_FILTER_ORDER = 5
_CORNER_MARGIN = 1e3
_FIT_POINTS = 300


# --------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------
def _positive_scalar(name: str, value: float) -> float:
    """Return ``value`` as a float, or raise ValueError naming ``name``.

    >>> _positive_scalar("dt", 0.5)
    0.5
    """
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite positive number, got {value!r}") from None
    if not (math.isfinite(out) and out > 0.0):
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    return out


def _positive_array(name: str, value: ArrayLike) -> np.ndarray:
    """Return ``value`` as a float array; all entries must be finite and > 0.

    >>> _positive_array("f_hz", [0.1, 1.0]).tolist()
    [0.1, 1.0]
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be finite positive number(s), got {value!r}") from None
    if arr.size == 0 or not np.all(np.isfinite(arr)) or not np.all(arr > 0.0):
        raise ValueError(f"{name} must be finite positive number(s), got {value!r}")
    return arr


def _check_order(order: int) -> int:
    """Validate the filter order (number of poles, 1..5).

    >>> _check_order(4)
    4
    """
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise ValueError(f"order must be an integer in 1..{_MAX_FILTER_ORDER}, got {order!r}")
    if not 1 <= int(order) <= _MAX_FILTER_ORDER:
        raise ValueError(f"order must be an integer in 1..{_MAX_FILTER_ORDER}, got {order!r}")
    return int(order)


# --------------------------------------------------------------------------
# the spectrum
# --------------------------------------------------------------------------
def _davenport_shape(x: np.ndarray) -> np.ndarray:
    """Normalised Davenport shape g(x) = x / (1 + x^2)^(4/3).

    ``S(f) = 4 kappa U L g(L f / U)``; ``integral_0^inf g(x) dx = 3/2``.

    >>> round(float(_davenport_shape(np.array(1.0))), 6)
    0.39685
    """
    return x / (1.0 + x * x) ** (4.0 / 3.0)


def davenport_psd(
    f_hz: ArrayLike,
    mean_speed: float,
    *,
    kappa: float = DAVENPORT_KAPPA,
    length: float = DAVENPORT_LENGTH_M,
) -> np.ndarray:
    """One-sided Davenport PSD of the along-wind gust velocity.

    ``S(f) = 4 kappa U^2 x^2 / (f (1 + x^2)^(4/3))`` with ``x = L f / U``.

    Parameters
    ----------
    f_hz : array_like
        Frequencies in Hz, finite and > 0.
    mean_speed : float
        Mean wind speed U at the 10-m reference height, m/s (> 0).
    kappa : float, optional
        Surface drag coefficient (default :data:`DAVENPORT_KAPPA`).
    length : float, optional
        Length scale L in m (default :data:`DAVENPORT_LENGTH_M`).

    Returns
    -------
    numpy.ndarray
        ``S(f)`` in (m/s)^2/Hz, same shape as ``f_hz``.

    Raises
    ------
    ValueError
        If any argument is not finite and positive (the message names it).

    Examples
    --------
    >>> round(float(davenport_psd(0.02, 50 / 3.6)), 2)
    91.14
    """
    f = _positive_array("f_hz", f_hz)
    u = _positive_scalar("mean_speed", mean_speed)
    k = _positive_scalar("kappa", kappa)
    big_l = _positive_scalar("length", length)
    x = big_l * f / u
    return 4.0 * k * u * u * x * x / (f * (1.0 + x * x) ** (4.0 / 3.0))


def davenport_variance(mean_speed: float, *, kappa: float = DAVENPORT_KAPPA) -> float:
    """Exact gust variance ``sigma_u^2 = 6 kappa U^2`` of the Davenport spectrum.

    Derivation: with ``x = L f / U`` one has ``df / f = dx / x``, so

    ``integral_0^inf S df = 4 kappa U^2 integral_0^inf x / (1 + x^2)^(4/3) dx``.

    Substituting ``t = x^2`` (``x dx = dt / 2``):
    ``integral = (1/2) integral_0^inf (1 + t)^(-4/3) dt
    = (1/2) [-3 (1 + t)^(-1/3)]_0^inf = 3/2``,
    hence ``sigma_u^2 = 4 kappa U^2 * 3/2 = 6 kappa U^2``, independent of L.

    Parameters
    ----------
    mean_speed : float
        Mean wind speed U at 10 m, m/s (> 0).
    kappa : float, optional
        Surface drag coefficient (default :data:`DAVENPORT_KAPPA`).

    Returns
    -------
    float
        Variance in (m/s)^2.

    Examples
    --------
    >>> round(davenport_variance(50 / 3.6) ** 0.5, 3)
    2.406
    """
    u = _positive_scalar("mean_speed", mean_speed)
    k = _positive_scalar("kappa", kappa)
    return 6.0 * k * u * u


def davenport_band_variance(
    mean_speed: float,
    f_low: float,
    f_high: float,
    *,
    kappa: float = DAVENPORT_KAPPA,
    length: float = DAVENPORT_LENGTH_M,
) -> float:
    """Integral of the Davenport PSD over ``f_low <= f <= f_high`` (closed form).

    From the derivation in :func:`davenport_variance`,
    ``integral_{f1}^{f2} S df = 6 kappa U^2 [(1 + x1^2)^(-1/3) - (1 + x2^2)^(-1/3)]``
    with ``x_i = L f_i / U``.  Note the slow ``f^(-2/3)`` convergence of the
    high-frequency tail: at 13.9 m/s about 1.1 % of the variance lies above 10 Hz.

    Parameters
    ----------
    mean_speed : float
        Mean wind speed U at 10 m, m/s (> 0).
    f_low, f_high : float
        Band edges in Hz, ``0 < f_low < f_high``; ``f_high`` may be ``inf``.
    kappa, length : float, optional
        Davenport constants (defaults :data:`DAVENPORT_KAPPA`, :data:`DAVENPORT_LENGTH_M`).

    Returns
    -------
    float
        Band variance in (m/s)^2.

    Examples
    --------
    >>> u = 50 / 3.6
    >>> round(davenport_band_variance(u, 1e-9, 10.0) / davenport_variance(u), 4)
    0.989
    """
    u = _positive_scalar("mean_speed", mean_speed)
    f1 = _positive_scalar("f_low", f_low)
    f2 = float(f_high)
    if not (f2 > f1) or math.isnan(f2):
        raise ValueError(f"f_high must be greater than f_low, got {f_high!r}")
    big_l = _positive_scalar("length", length)
    x1, x2 = big_l * f1 / u, big_l * f2 / u
    tail2 = 0.0 if math.isinf(x2) else (1.0 + x2 * x2) ** (-1.0 / 3.0)
    return davenport_variance(u, kappa=kappa) * ((1.0 + x1 * x1) ** (-1.0 / 3.0) - tail2)


# --------------------------------------------------------------------------
# spectral synthesis
# --------------------------------------------------------------------------
def _n_samples(duration: float, dt: float) -> int:
    """Number of samples ``round(duration / dt)``, at least 2.

    >>> _n_samples(10.0, 0.5)
    20
    """
    n = int(round(duration / dt))
    if n < 2:
        raise ValueError(f"duration must span at least 2 samples of dt, got duration={duration!r}, dt={dt!r}")
    return n


def generate_gusts(
    mean_speed: float,
    duration: float,
    dt: float,
    rng: np.random.Generator,
    *,
    kappa: float = DAVENPORT_KAPPA,
    length: float = DAVENPORT_LENGTH_M,
) -> np.ndarray:
    """Zero-mean gust velocity record with the Davenport spectrum.

    Spectral synthesis: for ``N = round(duration / dt)`` samples and
    ``df = 1 / (N dt)``, each positive frequency ``f_k = k df`` (k = 1..N//2)
    gets an independent cosine/sine pair with Gaussian amplitudes of variance
    ``S(f_k) df``; equivalently the rFFT coefficients are complex Gaussians
    ``X_k = (N / 2) sqrt(S(f_k) df) (g1 + i g2)`` (a real Gaussian of variance
    ``N^2 S df`` at the Nyquist bin of an even N) and the record is their
    inverse rFFT.  The DC bin is zero, so the record mean is exactly zero and
    its expected variance is ``sum_k S(f_k) df`` -- the Davenport integral
    over ``[df, 1 / (2 dt)]`` (see :func:`davenport_band_variance`).  The
    record is periodic with period ``duration``.

    Parameters
    ----------
    mean_speed : float
        Mean wind speed U at 10 m, m/s (> 0).
    duration : float
        Record length in s (> 0).
    dt : float
        Sample interval in s (> 0); ``duration / dt`` must round to >= 2.
    rng : numpy.random.Generator
        Source of every random draw; the same seed gives the same record.
    kappa, length : float, optional
        Davenport constants (defaults :data:`DAVENPORT_KAPPA`, :data:`DAVENPORT_LENGTH_M`).

    Returns
    -------
    numpy.ndarray
        Gust velocity ``u`` in m/s, shape ``(N,)``.

    Raises
    ------
    ValueError
        On a non-positive/non-finite argument or an ``rng`` that is not a
        :class:`numpy.random.Generator` (the message names the argument).

    Examples
    --------
    >>> u = generate_gusts(13.9, 600.0, 0.1, np.random.default_rng(1))
    >>> u.shape, abs(float(u.mean())) < 1e-12
    ((6000,), True)
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    u = _positive_scalar("mean_speed", mean_speed)
    t = _positive_scalar("duration", duration)
    h = _positive_scalar("dt", dt)
    n = _n_samples(t, h)
    df = 1.0 / (n * h)
    f = np.arange(1, n // 2 + 1) * df
    amp = np.sqrt(davenport_psd(f, u, kappa=kappa, length=length) * df)
    z = rng.standard_normal((2, f.size))
    spec = np.zeros(n // 2 + 1, dtype=complex)
    spec[1:] = 0.5 * n * amp * (z[0] + 1j * z[1])
    if n % 2 == 0:  # Nyquist bin: irfft keeps only the real part
        spec[-1] = n * amp[-1] * z[0, -1]
    return np.fft.irfft(spec, n=n)


# --------------------------------------------------------------------------
# the shaping filter
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class DavenportFit:
    """Rational fit ``G(p)`` of the normalised Davenport shape.

    ``G(p) = gain * prod_i (p + zeros_i) / prod_j (p + poles_j)`` in the
    normalised Laplace variable ``p`` (``p = j x`` on the imaginary axis,
    ``x = L f / U``), with ``|G(j x)|^2 ~ g(x) = x / (1 + x^2)^(4/3)``.
    Poles and zeros are real and negative (the tuples hold their magnitudes),
    so ``G`` is stable and minimum phase; it has ``order`` poles and
    ``order - 1`` zeros (strictly proper, relative degree 1).

    Attributes
    ----------
    order : int
        Number of poles.
    gain : float
        ``gain`` above (> 0).
    poles, zeros : tuple of float
        Magnitudes of the real poles and zeros, ascending.
    x_low, x_high : float
        Normalised band of the fit.
    max_log_error : float
        ``max |ln(|G|^2 / g)|`` on the fit grid.
    """

    order: int
    gain: float
    poles: tuple[float, ...]
    zeros: tuple[float, ...]
    x_low: float
    x_high: float
    max_log_error: float

    def shape(self, x: ArrayLike) -> np.ndarray:
        """Evaluate ``|G(j x)|^2`` at normalised frequencies ``x``.

        >>> fit = davenport_normalised_fit()
        >>> bool(abs(float(fit.shape(1.0)) / float(_davenport_shape(np.array(1.0))) - 1) < 0.2)
        True
        """
        return np.exp(_log_fit_shape(np.asarray(x, dtype=float), math.log(self.gain),
                                     np.asarray(self.poles), np.asarray(self.zeros)))


def _log_fit_shape(x: np.ndarray, log_gain: float, poles: np.ndarray, zeros: np.ndarray) -> np.ndarray:
    """``ln |G(j x)|^2`` for ``ln gain`` and real poles/zeros given by their magnitudes.

    >>> float(_log_fit_shape(np.array(0.0), np.log(2.0), np.array([1.0]), np.array([])))
    1.3862943611198906
    """
    x2 = np.asarray(x, dtype=float)[..., None] ** 2
    return (2.0 * log_gain - np.sum(np.log(x2 + poles**2), axis=-1)
            + np.sum(np.log(x2 + zeros**2), axis=-1))


def _initial_guess(order: int, x_low: float, x_high: float) -> np.ndarray:
    """Interlaced zero/pole corners spread log-uniformly over the band.

    Returns ``[ln gain, ln poles..., ln zeros...]`` (gain set later).

    >>> _initial_guess(2, 1.0, 1000.0).shape
    (4,)
    """
    corners = np.geomspace(x_low, x_high, 2 * order)
    zeros = corners[0::2][: order - 1]
    poles = corners[1::2]
    return np.concatenate([[0.0], np.log(poles), np.log(zeros)])


@functools.lru_cache(maxsize=16)
def davenport_normalised_fit(
    order: int = DEFAULT_FILTER_ORDER,
    x_low: float = FIT_X_LOW,
    x_high: float = FIT_X_HIGH,
) -> DavenportFit:
    """Fit the rational spectral factor ``G`` of the normalised Davenport shape.

    Least squares on ``ln|G(j x)|^2 - ln g(x)`` over 300 log-spaced points of
    ``[x_low, x_high]``, parametrised by the logarithms of the gain and of the
    real pole/zero magnitudes (so stability and minimum phase hold by
    construction), solved with Levenberg-Marquardt from a fixed interlaced
    start, then refined towards minimax by minimising ``sum |r|^q`` for
    q = 4, 8, 16, 32.  Deterministic; cached (computed once per argument set).

    Parameters
    ----------
    order : int, optional
        Number of poles, 1..5 (default :data:`DEFAULT_FILTER_ORDER`).
    x_low, x_high : float, optional
        Normalised band ``x = L f / U`` of the fit.

    Returns
    -------
    DavenportFit

    Examples
    --------
    >>> fit = davenport_normalised_fit(4)
    >>> len(fit.poles), len(fit.zeros), fit.max_log_error < 0.1
    (4, 3, True)
    """
    n = _check_order(order)
    lo = _positive_scalar("x_low", x_low)
    hi = _positive_scalar("x_high", x_high)
    if hi <= lo:
        raise ValueError(f"x_high must exceed x_low, got {x_high!r}")
    x = np.geomspace(lo, hi, _FIT_POINTS)
    target = np.log(_davenport_shape(x))
    # keep corners within 1e3 of the band: an unused pole/zero pair then parks
    # at the edge instead of overflowing
    log_min, log_max = math.log(lo / _CORNER_MARGIN), math.log(hi * _CORNER_MARGIN)

    def unpack(p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        corners = np.exp(np.clip(p[1:], log_min, log_max))
        return float(p[0]), corners[:n], corners[n:]

    def residual(p: np.ndarray) -> np.ndarray:
        log_gain, poles, zeros = unpack(p)
        return _log_fit_shape(x, log_gain, poles, zeros) - target

    p = _initial_guess(n, lo, hi)
    p[0] = -0.5 * float(np.mean(residual(p)))
    p = optimize.least_squares(residual, p, method="lm").x
    for q in (4, 8, 16, 32):
        def powered(p: np.ndarray, q: int = q) -> np.ndarray:
            r = residual(p)
            return np.sign(r) * np.abs(r) ** (q / 2)

        p = optimize.least_squares(powered, p, method="lm").x
    log_gain, poles, zeros = unpack(p)
    return DavenportFit(
        order=n,
        gain=math.exp(log_gain),
        poles=tuple(float(v) for v in np.sort(poles)),
        zeros=tuple(float(v) for v in np.sort(zeros)),
        x_low=lo,
        x_high=hi,
        max_log_error=float(np.max(np.abs(residual(p)))),
    )


def _cascade_realisation(fit: DavenportFit) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower-triangular state-space ``(A, B, C)`` of ``G(p)`` (D = 0).

    Cascade of ``1/(p + p_1)`` and the sections ``(p + z_i) / (p + p_{i+1})``:
    ``dx_1 = -p_1 x_1 + w``, ``dx_i = -p_i x_i + y_{i-1}``,
    ``y_i = y_{i-1} + (z_{i-1} - p_i) x_i``, output ``gain * y_n``.
    Needs no distinct poles and is well conditioned.

    >>> a, b, c = _cascade_realisation(davenport_normalised_fit(2))
    >>> a.shape, b.shape, c.shape
    ((2, 2), (2, 1), (1, 2))
    """
    n = fit.order
    poles, zeros = np.asarray(fit.poles), np.asarray(fit.zeros)
    a = np.zeros((n, n))
    b = np.zeros((n, 1))
    b[0, 0] = 1.0
    y = np.zeros(n)  # y_1 = x_1
    y[0] = 1.0
    a[0, 0] = -poles[0]
    for i in range(1, n):
        a[i, :] += y  # dx_i gets y_{i-1}
        a[i, i] = -poles[i]
        y = y.copy()
        y[i] += zeros[i - 1] - poles[i]
    return a, b, fit.gain * y[None, :]


def davenport_filter(
    mean_speed: float,
    order: int = DEFAULT_FILTER_ORDER,
    *,
    kappa: float = DAVENPORT_KAPPA,
    length: float = DAVENPORT_LENGTH_M,
) -> signal.StateSpace:
    """Continuous-time shaping filter from white noise to the gust velocity.

    Convention: the input ``w`` is white noise of unit *two-sided* intensity,
    ``E[w(t) w(t')] = delta(t - t')`` (units s^-1/2), the output is ``u`` in
    m/s, and the one-sided output PSD in (m/s)^2/Hz is
    ``S_filter(f) = 2 |H(j 2 pi f)|^2`` (:func:`filter_psd`), whose integral
    over ``f >= 0`` is the stationary variance ``C P C^T``
    (:func:`filter_variance`).

    Since ``S(f) = 4 kappa U L g(x)``, ``x = L f / U``, one rational fit
    ``|G(j x)|^2 ~ g(x)`` (:func:`davenport_normalised_fit`) serves every U:
    ``H(s) = sqrt(2 kappa U L) G(s tau)`` with ``tau = L / (2 pi U)``, i.e. the
    normalised poles/zeros are divided by ``tau`` (time scaling).  The filter
    is strictly proper (D = 0), asymptotically stable and minimum phase.

    Parameters
    ----------
    mean_speed : float
        Mean wind speed U at 10 m, m/s (> 0).
    order : int, optional
        Number of states (poles), 1..5; 4 (default) keeps the PSD within about
        7.5 % of Davenport for x in [0.1, 3000] (0.003-10 Hz for 4-36 m/s).
    kappa, length : float, optional
        Davenport constants (defaults :data:`DAVENPORT_KAPPA`, :data:`DAVENPORT_LENGTH_M`).

    Returns
    -------
    scipy.signal.StateSpace
        SISO continuous-time system ``(A, B, C, D=0)``.

    Examples
    --------
    >>> ss = davenport_filter(50 / 3.6)
    >>> ss.A.shape, bool(np.all(np.linalg.eigvals(ss.A).real < 0)), float(ss.D[0, 0])
    ((4, 4), True, 0.0)
    """
    u = _positive_scalar("mean_speed", mean_speed)
    k = _positive_scalar("kappa", kappa)
    big_l = _positive_scalar("length", length)
    a_n, b_n, c_n = _cascade_realisation(davenport_normalised_fit(_check_order(order)))
    tau = big_l / (2.0 * math.pi * u)
    scale = math.sqrt(2.0 * k * u * big_l)
    root_tau = math.sqrt(tau)
    return signal.StateSpace(a_n / tau, b_n / root_tau, scale * c_n / root_tau, np.zeros((1, 1)))


def filter_psd(ss: signal.StateSpace, f_hz: ArrayLike) -> np.ndarray:
    """One-sided output PSD ``2 |H(j 2 pi f)|^2`` of a SISO filter driven by unit white noise.

    Parameters
    ----------
    ss : scipy.signal.StateSpace
        Continuous-time SISO system.
    f_hz : array_like
        Frequencies in Hz (> 0).

    Returns
    -------
    numpy.ndarray
        PSD in (output unit)^2/Hz, same shape as ``f_hz``.

    Examples
    --------
    >>> lp = signal.StateSpace([[-1.0]], [[1.0]], [[1.0]], [[0.0]])
    >>> round(float(filter_psd(lp, 1 / (2 * np.pi))), 6)   # 2 / (1 + 1)
    1.0
    """
    f = _positive_array("f_hz", f_hz)
    a, b, c, d = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    s = 2j * np.pi * f.reshape(-1)
    eye = np.eye(a.shape[0])
    resolvent_b = np.linalg.solve(s[:, None, None] * eye - a, np.broadcast_to(b, (s.size,) + b.shape))
    h = (c @ resolvent_b)[:, 0, 0] + d[0, 0]
    return (2.0 * np.abs(h) ** 2).reshape(f.shape)


def filter_variance(ss: signal.StateSpace) -> float:
    """Stationary output variance of a SISO filter driven by unit white noise.

    Solves ``A P + P A^T + B B^T = 0`` and returns ``C P C^T`` (equal to the
    integral of :func:`filter_psd` over ``f >= 0``).  Requires ``D = 0`` and a
    stable ``A`` (otherwise the variance is infinite: ValueError).

    Parameters
    ----------
    ss : scipy.signal.StateSpace
        Continuous-time SISO system.

    Returns
    -------
    float
        Variance in (output unit)^2.

    Examples
    --------
    >>> lp = signal.StateSpace([[-2.0]], [[1.0]], [[1.0]], [[0.0]])
    >>> filter_variance(lp)   # 1 / (2 a)
    0.25
    """
    a, b, c, d = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    if np.any(d != 0.0):
        raise ValueError("ss must be strictly proper (D = 0) for a finite variance")
    if np.any(np.linalg.eigvals(a).real >= 0.0):
        raise ValueError("ss must be asymptotically stable for a finite variance")
    p = linalg.solve_continuous_lyapunov(a, -b @ b.T)
    return float((c @ p @ c.T)[0, 0])


def davenport_filter_fit_error(
    mean_speed: float,
    order: int = DEFAULT_FILTER_ORDER,
    *,
    f_low: float = 0.003,
    f_high: float = 10.0,
    n_points: int = 2000,
    kappa: float = DAVENPORT_KAPPA,
    length: float = DAVENPORT_LENGTH_M,
) -> float:
    """Max relative PSD error ``max |S_filter / S - 1|`` of :func:`davenport_filter`.

    Evaluated from the scaled state-space model itself on ``n_points``
    log-spaced frequencies of ``[f_low, f_high]``.

    Parameters
    ----------
    mean_speed : float
        Mean wind speed U at 10 m, m/s (> 0).
    order : int, optional
        Filter order (see :func:`davenport_filter`).
    f_low, f_high : float, optional
        Band in Hz (default 0.003-10 Hz).
    n_points : int, optional
        Number of grid points (>= 2).
    kappa, length : float, optional
        Davenport constants.

    Returns
    -------
    float
        Max relative error (0.2 means 20 %).

    Examples
    --------
    >>> davenport_filter_fit_error(50 / 3.6) < 0.1
    True
    """
    lo = _positive_scalar("f_low", f_low)
    hi = _positive_scalar("f_high", f_high)
    if hi <= lo:
        raise ValueError(f"f_high must exceed f_low, got {f_high!r}")
    if int(n_points) < 2:
        raise ValueError(f"n_points must be >= 2, got {n_points!r}")
    f = np.geomspace(lo, hi, int(n_points))
    ss = davenport_filter(mean_speed, order, kappa=kappa, length=length)
    ratio = filter_psd(ss, f) / davenport_psd(f, mean_speed, kappa=kappa, length=length)
    return float(np.max(np.abs(ratio - 1.0)))


# --------------------------------------------------------------------------
# plot
# --------------------------------------------------------------------------
def plot_gust_psd(
    mean_speed: float,
    rng: np.random.Generator,
    path: PathLike,
    *,
    duration: float = 6 * 3600.0,
    dt: float = 0.05,
    nperseg: int = 2**16,
    order: int = DEFAULT_FILTER_ORDER,
    kappa: float = DAVENPORT_KAPPA,
    length: float = DAVENPORT_LENGTH_M,
) -> str:
    """Save a log-log plot of the gust PSD: Welch estimate, formula and filter.

    Generates a record with :func:`generate_gusts`, estimates its one-sided
    PSD with :func:`scipy.signal.welch` (Hann, ``nperseg`` samples), and plots
    it with :func:`davenport_psd` and :func:`filter_psd` of
    :func:`davenport_filter` over the record's band.  Matplotlib is imported
    lazily and the figure is drawn on an off-screen Agg canvas
    (:class:`matplotlib.figure.Figure`), so pyplot's backend is left alone.

    Parameters
    ----------
    mean_speed : float
        Mean wind speed U at 10 m, m/s (> 0).
    rng : numpy.random.Generator
        Random source for the record.
    path : str or os.PathLike
        Output PNG file.
    duration, dt : float, optional
        Record length and sample interval in s (default 6 h at 0.05 s).
    nperseg : int, optional
        Welch segment length (default 65536 samples = 3277 s: 0.3 mHz bins).
    order, kappa, length : optional
        Filter order and Davenport constants.

    Returns
    -------
    str
        The path written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    gusts = generate_gusts(mean_speed, duration, dt, rng, kappa=kappa, length=length)
    f_w, p_w = signal.welch(gusts, fs=1.0 / dt, nperseg=min(int(nperseg), gusts.size))
    keep = f_w > 0
    f_w, p_w = f_w[keep], p_w[keep]
    f = np.geomspace(f_w[0], f_w[-1], 400)
    ss = davenport_filter(mean_speed, order, kappa=kappa, length=length)
    fig = Figure(figsize=(7, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.loglog(f_w, p_w, color="0.7", lw=0.8, label="Welch PSD of generated record")
    ax.loglog(f, davenport_psd(f, mean_speed, kappa=kappa, length=length), "k", lw=1.5,
              label="Davenport formula")
    ax.loglog(f, filter_psd(ss, f), "r--", lw=1.2, label=f"shaping filter (order {ss.A.shape[0]})")
    ax.axvspan(0.003, 10.0, color="C0", alpha=0.06, label="0.003-10 Hz band")
    ax.set_xlabel("frequency f [Hz]")
    ax.set_ylabel("S(f) [(m/s)$^2$/Hz]")
    ax.set_title(f"Along-wind gust PSD, U = {mean_speed:.2f} m/s at 10 m")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)
    return os.fspath(path)
