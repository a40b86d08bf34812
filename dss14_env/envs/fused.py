"""The vector environment's step compiled (numba): the batched pieces of
:mod:`dss14_env.envs.core` fused into two loops over the sub-environments.

:func:`before_product` is :func:`~dss14_env.envs.core.limit_commands` and the plant product's
input rows; :func:`after_product` is :func:`~dss14_env.envs.core.read_encoders`,
:func:`~dss14_env.envs.core.servo_errors`, :func:`~dss14_env.envs.core.terminated`,
:func:`~dss14_env.envs.core.pointing_errors`, :func:`~dss14_env.envs.core.reward`,
:func:`~dss14_env.envs.core.observation` and the values of
:func:`~dss14_env.envs.core.step_info`.  Each makes the same floating-point operations in the
same order as the pieces, so the results are the same bit for bit (``tests/test_env_fused.py``
holds them equal on random inputs, limiter edges, signed zeros, quantisation, termination and
clamping included).

Why: a batched piece is one numpy call per operation on ``(N, 2)`` arrays, about a microsecond
each at N = 1 024, and a step makes about a hundred of them (some 75 µs a step); the two
compiled loops take about 20 µs.  numba is optional (the ``fast`` extra): without it
:data:`AVAILABLE` is False and the vector environment steps with the batched pieces.  The loops
are compiled in memory on first use (about a second), never cached to disk.

Without numba the functions below are plain Python (slow, but the same results): the tests
run them so where numba is missing.
"""

from __future__ import annotations

import math

import numpy as np

from dss14_env.core.units import R2D, R2MD
from dss14_env.envs.core import OBS_ERROR_BOUND, OBS_ERROR_RATE_BOUND, StepConstants

try:
    from numba import njit
except ImportError:  # pragma: no cover - exercised where numba is missing
    njit = None

#: whether the compiled step is available (numba installed)
AVAILABLE = njit is not None

#: the float info values :func:`after_product` writes, one row each, in order
INFO_FLOAT_ROWS = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg",
                   "measured_error_el_mdeg", "pointing_error_el_mdeg", "pointing_error_xel_mdeg",
                   "wind_speed_mps", "wind_direction_rad", "rate_command_az_deg_s", "rate_command_el_deg_s")
#: the integer info values (the episode's limiter hit counts after the step)
INFO_INT_ROWS = ("n_rate_limited", "n_accel_limited")

# the entries of the constants vector (:func:`constants`)
(_SCALE, _RATE_CLIP, _RL, _DR, _SIGMA, _QUANTUM, _INV_Q, _AZ_CENTRE, _EL_LO, _EL_HI, _AZ_H, _XEL, _INV_ES2,
 _W, _PENALTY, _POINTING, _INV_ES, _RATE_SCALE, _INV_RL, _N_CONSTANTS) = range(20)
#: :func:`after_product`'s result flags
ANY_TERMINATED, NON_FINITE = 1, 2


def constants(k: StepConstants, xel_scale: float) -> np.ndarray:
    """The step's constants as one float vector (flags as 0.0 / 1.0), each computed as the
    batched pieces compute it.
    """
    c = np.zeros(_N_CONSTANTS)
    c[_SCALE], c[_RATE_CLIP], c[_RL], c[_DR] = k.action_scale, k.rate_clip, k.rate_limit, k.rate_step
    c[_SIGMA], c[_QUANTUM] = k.encoder_sigma, k.quantum
    c[_INV_Q] = k.inv_quantum
    c[_AZ_CENTRE], (c[_EL_LO], c[_EL_HI]), c[_AZ_H] = k.az_centre, k.el_limits, k.az_half_range
    c[_XEL] = xel_scale
    c[_INV_ES2], c[_W] = k.inv_error_scale * k.inv_error_scale, k.action_change_weight
    c[_PENALTY], c[_POINTING] = k.termination_penalty, k.pointing_reward
    c[_INV_ES], c[_RATE_SCALE], c[_INV_RL] = k.inv_error_scale, k.error_rate_scale, k.inv_rate_limit
    return c


def _max(x: float, lo: float) -> float:
    """``np.maximum`` on two finite floats: the second where they compare equal, as numpy's
    loops do (it decides the sign of a zero).
    """
    return x if x > lo else lo


def _min(x: float, hi: float) -> float:
    """``np.minimum`` on two finite floats (the second where equal)."""
    return x if x < hi else hi


def before_product(A: np.ndarray, r_prev: np.ndarray, kc: np.ndarray, perm: np.ndarray, kappa_s: np.ndarray,
                   t_mean_s: np.ndarray, normals: np.ndarray, noise_on: bool, n: int, k: int, Z: np.ndarray,
                   a_out: np.ndarray, r_out: np.ndarray, rate_hit: np.ndarray, acc_hit: np.ndarray) -> None:
    """The command limiter of every sub-environment (:func:`~dss14_env.envs.core.limit_commands`)
    and the plant product's input rows ``n ..`` of this step in slot order (sub-environment
    ``perm[s]`` in slot ``s``): the applied rate commands, the mean wind torques and, with
    ``noise_on``, the gust normals scaled by the direction factors.

    :param A: actions ``(N, 2)`` float64, finite; ``r_prev`` the previous rate commands, rad/s
    :param kc: :func:`constants`
    :param kappa_s: direction factors ``(2, N)`` and ``t_mean_s`` mean torques ``(2, N)``, in
        slot order
    :param normals: this step's standard normals ``(N, >= k)``, the gust's first
    :param Z: the product's input ``(n + 4 + 2 k, N)``
    :param a_out: receives the clipped actions ``(N, 2)``, ``r_out`` the applied rate commands,
        ``rate_hit`` and ``acc_hit`` ``(N,)`` whether the rate clip / acceleration limit acted
    """
    scale, rate_clip, rl, dr = kc[_SCALE], kc[_RATE_CLIP] != 0.0, kc[_RL], kc[_DR]
    N = A.shape[0]
    for i in range(N):
        c0 = _min(_max(A[i, 0], -1.0), 1.0)
        c1 = _min(_max(A[i, 1], -1.0), 1.0)
        a_out[i, 0] = c0
        a_out[i, 1] = c1
        q0 = c0 * scale
        q1 = c1 * scale
        if rate_clip:
            rate_hit[i] = (abs(q0) > rl) | (abs(q1) > rl)
            q0 = _min(_max(q0, -rl), rl)
            q1 = _min(_max(q1, -rl), rl)
        else:
            rate_hit[i] = False
        r0 = _min(_max(q0, r_prev[i, 0] - dr), r_prev[i, 0] + dr)
        r1 = _min(_max(q1, r_prev[i, 1] - dr), r_prev[i, 1] + dr)
        r_out[i, 0] = r0
        r_out[i, 1] = r1
        acc_hit[i] = (r0 != q0) | (r1 != q1)
    for s in range(N):
        i = perm[s]
        Z[n, s] = r_out[i, 0]
        Z[n + 1, s] = r_out[i, 1]
        Z[n + 2, s] = t_mean_s[0, s]
        Z[n + 3, s] = t_mean_s[1, s]
        if noise_on:
            for m in range(k):
                Z[n + 4 + m, s] = normals[i, m] * kappa_s[0, s]
                Z[n + 4 + k + m, s] = normals[i, m] * kappa_s[1, s]


def after_product(Y: np.ndarray, inv: np.ndarray, c: np.ndarray, cd: np.ndarray, start: np.ndarray,
                  normals: np.ndarray, k: int, max_e: np.ndarray, a: np.ndarray, a_prev: np.ndarray,
                  em_prev: np.ndarray, r: np.ndarray, wind: np.ndarray, rate_hit: np.ndarray,
                  acc_hit: np.ndarray, hits: np.ndarray, kc: np.ndarray, clamp_always: bool, obs: np.ndarray,
                  rew: np.ndarray, term: np.ndarray, em: np.ndarray, info_f: np.ndarray, info_i: np.ndarray
                  ) -> int:
    """Everything of a step after the plant product, for every sub-environment: encoders,
    servo and pointing errors, episode end, reward, observation (float32), the info values and
    the limiter hit counts.

    :param Y: the product's step outputs ``(4, N)`` in slot order (encoder angles az, el;
        pointing angles el, xel; rad), sub-environment ``i`` in slot ``inv[i]``
    :param c: commands ``(N, 2)``, rad; ``cd`` their rates, rad/s
    :param normals: this step's standard normals ``(N, k [+ 2])``; with encoder noise its
        columns ``k``, ``k + 1`` are the encoders' (az, el)
    :param max_e: the servo error bounds ``(N,)``, mdeg
    :param a: clipped actions ``(N, 2)``, ``a_prev`` the previous ones; ``em_prev`` the previous
        measured errors (mdeg); ``r`` the applied rate commands (rad/s)
    :param wind: ``[speed, direction]`` ``(N, 2)``
    :param hits: the episodes' limiter hit counts ``(N, 2)``, advanced by ``rate_hit`` and
        ``acc_hit`` when every reward is finite
    :param clamp_always: clamp the observation's errors whether or not a sub-environment
        terminated (:meth:`~dss14_env.envs.core.StepConstants.clamp_always`)
    :param obs: receives the observations ``(N, 12)`` float32, ``rew``, ``term`` ``(N,)``, ``em``
        the measured errors ``(N, 2)``, ``info_f`` the rows :data:`INFO_FLOAT_ROWS` ``(10, N)``,
        ``info_i`` the rows :data:`INFO_INT_ROWS` ``(2, N)``
    :return: flags: :data:`ANY_TERMINATED`, :data:`NON_FINITE` (a reward is NaN or infinite;
        the hit counts are then left as they were)
    """
    sigma, quantum, inv_q = kc[_SIGMA], kc[_QUANTUM], kc[_INV_Q]
    az_centre, el_lo, el_hi, az_h, xel = kc[_AZ_CENTRE], kc[_EL_LO], kc[_EL_HI], kc[_AZ_H], kc[_XEL]
    inv_es2, w, penalty, pointing = kc[_INV_ES2], kc[_W], kc[_PENALTY], kc[_POINTING] != 0.0
    inv_es, rate_scale, inv_rl = kc[_INV_ES], kc[_RATE_SCALE], kc[_INV_RL]
    N = a.shape[0]
    any_term = False
    total = 0.0
    for i in range(N):
        s = inv[i]
        th0, th1 = Y[0, s], Y[1, s]
        s0, s1 = start[i, 0], start[i, 1]
        # read_encoders
        x0 = s0 + th0
        x1 = s1 + th1
        if sigma != 0.0:
            x0 += normals[i, k] * sigma
            x1 += normals[i, k + 1] * sigma
        if quantum != 0.0:
            x0 = math.floor(x0 * inv_q + 0.5) * quantum
            x1 = math.floor(x1 * inv_q + 0.5) * quantum
        rel0 = x0 - s0
        rel1 = x1 - s1
        # servo_errors
        c0, c1 = c[i, 0], c[i, 1]
        em0 = (c0 - rel0) * R2MD
        em1 = (c1 - rel1) * R2MD
        e0 = (c0 - th0) * R2MD
        e1 = (c1 - th1) * R2MD
        em[i, 0] = em0
        em[i, 1] = em1
        # terminated (beyond_bounds)
        el = s1 + th1
        az_off = (s0 - az_centre) + th0
        me = max_e[i]
        t = (abs(e0) > me) | (abs(e1) > me) | (el < el_lo) | (el > el_hi) | (abs(az_off) > az_h)
        term[i] = t
        any_term |= t
        # pointing_errors
        pe0 = (c1 - Y[2, s]) * R2MD
        pe1 = (c0 * xel - Y[3, s]) * R2MD
        # reward: step_cost of the scored errors, the penalty where terminated
        q0, q1 = (pe0, pe1) if pointing else (e0, e1)
        d0 = a[i, 0] - a_prev[i, 0]
        d1 = a[i, 1] - a_prev[i, 1]
        cost = (q0 * q0 + q1 * q1) * inv_es2 + w * (d0 * d0 + d1 * d1)
        if t:
            cost += penalty
        rew[i] = -cost
        total += cost
        # observation (layout OBS); the errors and error rates clamped below
        obs[i, 0] = em0 * inv_es
        obs[i, 1] = em1 * inv_es
        obs[i, 2] = (em0 - em_prev[i, 0]) * rate_scale
        obs[i, 3] = (em1 - em_prev[i, 1]) * rate_scale
        obs[i, 4] = c0 * R2D
        obs[i, 5] = c1 * R2D
        obs[i, 6] = cd[i, 0] * inv_rl
        obs[i, 7] = cd[i, 1] * inv_rl
        obs[i, 8] = rel0 * R2D
        obs[i, 9] = rel1 * R2D
        obs[i, 10] = r[i, 0] * inv_rl
        obs[i, 11] = r[i, 1] * inv_rl
        # info
        info_f[0, i] = e0
        info_f[1, i] = e1
        info_f[2, i] = em0
        info_f[3, i] = em1
        info_f[4, i] = pe0
        info_f[5, i] = pe1
        info_f[6, i] = wind[i, 0]
        info_f[7, i] = wind[i, 1]
        info_f[8, i] = r[i, 0] * R2D
        info_f[9, i] = r[i, 1] * R2D
    if any_term or clamp_always:  # the clamp of observation(), from the unrounded values
        for i in range(N):
            obs[i, 0] = _clamped(em[i, 0] * inv_es, OBS_ERROR_BOUND)
            obs[i, 1] = _clamped(em[i, 1] * inv_es, OBS_ERROR_BOUND)
            obs[i, 2] = _clamped((em[i, 0] - em_prev[i, 0]) * rate_scale, OBS_ERROR_RATE_BOUND)
            obs[i, 3] = _clamped((em[i, 1] - em_prev[i, 1]) * rate_scale, OBS_ERROR_RATE_BOUND)
    if not math.isfinite(total):  # NaN or infinite: some reward is
        return ANY_TERMINATED * any_term + NON_FINITE
    for i in range(N):
        hits[i, 0] += rate_hit[i]
        hits[i, 1] += acc_hit[i]
        info_i[0, i] = hits[i, 0]
        info_i[1, i] = hits[i, 1]
    return ANY_TERMINATED * any_term


def _clamped(x: float, b: float) -> float:
    """``x`` clamped to ``[-b, b]`` as :func:`~dss14_env.envs.core.observation` clamps."""
    return _min(_max(x, -b), b)


if AVAILABLE:
    _max = njit(inline="always")(_max)
    _min = njit(inline="always")(_min)
    _clamped = njit(inline="always")(_clamped)
    before_product = njit(nogil=True)(before_product)
    after_product = njit(nogil=True)(after_product)
