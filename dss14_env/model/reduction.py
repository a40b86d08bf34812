"""Modal reduction by Hankel singular values, [R] Eq. (55).

For a lightly damped mode with distinct frequency the modal form is almost balanced, and the
Hankel singular value of mode ``i`` is, [R] Eq. (55) with [R] refs. [11]-[12]::

    gamma_i = w_b beta_i sqrt(w_q^2 alpha_q^2 + w_r^2 omega_i^2 alpha_r^2) / (4 zeta_i omega_i^2)

with ``beta_i = ||b_i||`` (row i of M_m^-1 Phi^T B_o), ``alpha_q = ||c_qi||`` and
``alpha_r = ||c_ri||`` (column i of the displacement and rate output matrices).  The report
prints the left side as ``gamma_i^2`` with alpha as squared norms; that reading is not
dimensionally consistent, and the form above is the one of Gawronski's *Balanced Control of
Flexible Structures* (ref. [12]); :func:`exact_mode_hsv` checks it against the balanced
gramians.  Rigid-body modes have infinite values and are always kept.

>>> import numpy as np
>>> from dss14_env.model.structure import ModalModel
>>> m = ModalModel(np.array([0.0, 10.0, 20.0]), np.array([0.0, .01, .01]), np.ones(3),
...                np.ones((3, 1)), np.zeros((1, 3)), np.ones((1, 3)), (0,), ("u",), ("y",))
>>> hsv = hankel_singular_values(m)
>>> bool(np.isinf(hsv[0])), round(float(hsv[1]), 3), round(float(hsv[2]), 3)
(True, 2.5, 1.25)
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from dss14_env.model.structure import ModalModel


def hankel_singular_values(m: ModalModel, w_b=1.0, w_q=1.0, w_r=1.0,
                           input_scale=None, output_scale=None) -> np.ndarray:
    """Approximate Hankel singular value of each mode, Eq. (55).

    :param m: modal model
    :param w_b: input weight per mode (scalar or array), default 1
    :param w_q: displacement-output weight per mode, default 1
    :param w_r: rate-output weight per mode, default 1
    :param input_scale: factor per input column, making the units consistent (e.g. pinion
        torque to axis-torque equivalent); default all 1
    :param output_scale: factor per output row; default all 1
    :return: array of gamma_i, ``inf`` for the rigid-body modes
    """
    b = m.b * (1.0 if input_scale is None else np.asarray(input_scale)[None, :])
    osc = 1.0 if output_scale is None else np.asarray(output_scale)[:, None]
    cq, cv = m.cq * osc, m.cv * osc
    beta = np.linalg.norm(b, axis=1)
    aq, ar = np.linalg.norm(cq, axis=0), np.linalg.norm(cv, axis=0)
    w = m.omega
    with np.errstate(divide="ignore", invalid="ignore"):
        g = (np.asarray(w_b) * beta * np.sqrt((np.asarray(w_q) * aq) ** 2
                                             + (np.asarray(w_r) * w * ar) ** 2)
             / (4.0 * m.zeta * w ** 2))
    g = np.asarray(g, float)
    g[list(m.rigid)] = np.inf
    return g


def reduce_modes(m: ModalModel, n_flexible: int, **weights) -> tuple[ModalModel, np.ndarray]:
    """Keep the rigid-body modes and the ``n_flexible`` flexible modes of largest Eq. (55) value.

    :param m: full modal model
    :param n_flexible: number of flexible modes to keep ([R]: 22)
    :param weights: passed to :func:`hankel_singular_values`
    :return: the reduced model (modes in ascending frequency) and the kept mode indices
    """
    if not 0 <= n_flexible <= m.n_modes - len(m.rigid):
        raise ValueError(f"n_flexible must be in [0, {m.n_modes - len(m.rigid)}], got {n_flexible}")
    g = hankel_singular_values(m, **weights)
    keep = np.argsort(-g, kind="stable")[: len(m.rigid) + n_flexible]
    keep = keep[np.argsort(m.omega[keep], kind="stable")]
    return m.select(keep), keep


def exact_mode_hsv(m: ModalModel, i: int, input_scale=None, output_scale=None) -> float:
    """Largest exact Hankel singular value of flexible mode ``i`` alone (balanced gramians)."""
    w, z = m.omega[i], m.zeta[i]
    b = m.b[i] * (1.0 if input_scale is None else np.asarray(input_scale))
    osc = 1.0 if output_scale is None else np.asarray(output_scale)
    A = np.array([[0.0, 1.0], [-w * w, -2 * z * w]])
    B = np.vstack([np.zeros_like(b), b])
    C = np.column_stack([m.cq[:, i] * osc, m.cv[:, i] * osc])
    Wc = scipy.linalg.solve_continuous_lyapunov(A, -B @ B.T)
    Wo = scipy.linalg.solve_continuous_lyapunov(A.T, -C.T @ C)
    return float(np.sqrt(np.max(np.linalg.eigvals(Wc @ Wo).real)))
