"""The step of the DSS14 environments, written once: the command limiter, encoders, servo and
pointing errors, episode end, reward, observation and info values, as compiled loops over N
sub-environments (numba), and the reset's first observation and info through the same loop.

The single environment (:mod:`dss14_env.envs.env`) runs them with N = 1 on its preallocated
step buffers; the vector environment (:mod:`dss14_env.envs.vector`) with its N; between the two
loops each runs the plant map of its own layout, one numpy matrix product
(:mod:`dss14_env.envs.plant`)::

    limit_commands            actions -> clipped actions, applied rate commands, limiter flags
    [plant map]               [x+, y+] = M [x, r, wind, gust noise]
    after_product             encoders, errors, episode end, reward, observation, info values

Why compiled loops: a step of one environment is a few dozen floating-point operations.  As
numpy operations on ``(N, 2)`` arrays each costs about a microsecond whatever N (a hundred of
them per step), so the single environment used to carry a second copy of the step on Python
floats; a compiled loop serves N = 1 and N = 1 024 alike, with the call's dispatch (well
under a microsecond per call with these arguments) as its only fixed cost.  The plant product
stays numpy's (the same BLAS call as before, so the same bits): a product inside the loop would
sum in another order.  ``NUMBA_DISABLE_JIT=1`` runs this very source as Python (slow; the
results are the same).  The loops are compiled in memory on first use, once per process and
kind of environment (10-12 s measured on a 2-core machine at load average 8, by
``scripts/bench_env_speed.py``); they are not cached to disk: numba's cache (``cache=True``)
writes next to the installed package or into a user folder, and reads its index back with
pickle, which nothing this package writes may need.

The step, in order (SI inside; mdeg and deg at the interface)::

    a      = clip(action, -1, 1)                                       action units
    q      = clip(a * action_scale, +-rate_limit)                      rad/s (rate clip)
    r      = clip(q, r_prev - rate_step, r_prev + rate_step)           acceleration limit
    x+, y+ = plant map (exact discretisation, :mod:`dss14_env.envs.plant`)
    reading = q_enc * floor((start + theta + noise) / q_enc + 1/2)      encoder (absolute angle)
    e      = (c - theta) * R2MD,   e_meas = (c - (reading - start)) * R2MD      servo errors, mdeg
    terminated = |e| > max_error on an axis, or the antenna leaves its travel
    pointing error p = [c_el - point_el, c_az cos(E) - point_xel] * R2MD
    reward = -((s_1^2 + s_2^2) / error_scale^2 + w ||a - a_prev||^2) [- penalty if terminated]
             s = e (``reward: servo``, the default) or s = p (``reward: pointing``)

>>> import numpy as np
>>> from dss14_env.core.units import R2D
>>> from dss14_env.envs.config import load_env_config
>>> from dss14_env.envs.core import StepConstants
>>> kc = constants(StepConstants.from_config(load_env_config()), 0.7)
>>> a, r, hit = np.empty((1, 2)), np.empty((1, 2)), np.empty((2, 1))
>>> limit_commands(np.array([[2.0, -0.01]]), np.zeros((1, 2)), kc, a, r, hit)
-1
>>> a.tolist(), (r * R2D).round(6).tolist(), hit.ravel().tolist()
([[1.0, -0.01]], [[0.004, -0.0025]], [0.0, 1.0])
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from dss14_env.core.units import R2D, R2MD
from dss14_env.envs.core import (
    OBS_ERROR_BOUND,
    OBS_ERROR_RATE_BOUND,
    OBS_SIZE,
    RESET_INFO_KEYS,
    StepConstants,
    StepState,
)
from dss14_env.envs.plant import N_STEP_OUTPUTS

#: the float info values :func:`after_product` writes, one row each, in order
INFO_FLOAT_ROWS = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg",
                   "measured_error_el_mdeg", "pointing_error_el_mdeg", "pointing_error_xel_mdeg",
                   "wind_speed_mps", "wind_direction_rad", "rate_command_az_deg_s", "rate_command_el_deg_s")
#: the integer info values (the episode's limiter hit counts after the step)
INFO_INT_ROWS = ("n_rate_limited", "n_accel_limited")
#: the rows of :func:`after_product`'s ``out``: :data:`INFO_FLOAT_ROWS`, the reward, whether the
#: episode terminated (1.0 or 0.0) and :data:`INFO_INT_ROWS` (as floats)
REWARD_ROW, TERMINATED_ROW = len(INFO_FLOAT_ROWS), len(INFO_FLOAT_ROWS) + 1
OUT_ROWS = len(INFO_FLOAT_ROWS) + 2 + len(INFO_INT_ROWS)
#: the rows of the pointing errors ``[el, xel]`` in :data:`INFO_FLOAT_ROWS`
POINTING_ROWS = (INFO_FLOAT_ROWS.index("pointing_error_el_mdeg"),
                 INFO_FLOAT_ROWS.index("pointing_error_xel_mdeg"))

# the entries of the constants vector (:func:`constants`)
(_SCALE, _RATE_CLIP, _RL, _DR, _SIGMA, _QUANTUM, _INV_Q, _AZ_CENTRE, _EL_LO, _EL_HI, _AZ_H, _XEL, _INV_ES2,
 _W, _PENALTY, _POINTING, _INV_ES, _RATE_SCALE, _INV_RL, _N_CONSTANTS) = range(20)
#: :func:`after_product`'s encoder noise where there is none (not read)
NO_NOISE = np.zeros((1, 1, 2))
#: :func:`after_product`'s result flags
ANY_TERMINATED, NON_FINITE = 1, 2


def constants(k: StepConstants, xel_scale: float) -> np.ndarray:
    """The step's constants as one float vector (flags as 0.0 / 1.0).

    :param xel_scale: ``cos(E)`` of the structure model: the cross-elevation command is the
        azimuth command times it, as in the structure model's xel output
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


@njit(inline="always")
def _max(x: float, lo: float) -> float:
    """The larger of two finite floats, the second where they compare equal (as ``np.maximum``;
    it decides the sign of a zero).
    """
    return x if x > lo else lo


@njit(inline="always")
def _min(x: float, hi: float) -> float:
    """The smaller of two finite floats (the second where equal)."""
    return x if x < hi else hi


@njit(inline="always")
def _clamped(x: float, b: float) -> float:
    """``x`` clamped to ``[-b, b]``."""
    return _min(_max(x, -b), b)


@njit(nogil=True)
def limit_commands(A: np.ndarray, r_prev: np.ndarray, kc: np.ndarray, a_out: np.ndarray, r_out: np.ndarray,
                   hit: np.ndarray) -> int:
    """The command limiter of every sub-environment.

    :param A: actions ``(N, 2)`` float64; ``r_prev`` the previous applied rate commands, rad/s;
        ``kc`` :func:`constants`
    :param a_out: receives the actions clipped to [-1, 1] ``(N, 2)``, ``r_out`` the applied
        rate commands (rad/s), ``hit`` ``(2, N)`` whether the rate clip (row 0) / the
        acceleration limit (row 1) acted (1.0 or 0.0)
    :return: -1, or the first row with a non-finite action (then nothing is written)
    """
    N = A.shape[0]
    for i in range(N):
        if not (math.isfinite(A[i, 0]) and math.isfinite(A[i, 1])):
            return i
    scale, rate_clip, rl, dr = kc[_SCALE], kc[_RATE_CLIP] != 0.0, kc[_RL], kc[_DR]
    for i in range(N):
        c0 = _min(_max(A[i, 0], -1.0), 1.0)
        c1 = _min(_max(A[i, 1], -1.0), 1.0)
        a_out[i, 0] = c0
        a_out[i, 1] = c1
        q0 = c0 * scale
        q1 = c1 * scale
        if rate_clip:
            hit[0, i] = (abs(q0) > rl) | (abs(q1) > rl)
            q0 = _min(_max(q0, -rl), rl)
            q1 = _min(_max(q1, -rl), rl)
        else:
            hit[0, i] = False
        r0 = _min(_max(q0, r_prev[i, 0] - dr), r_prev[i, 0] + dr)
        r1 = _min(_max(q1, r_prev[i, 1] - dr), r_prev[i, 1] + dr)
        r_out[i, 0] = r0
        r_out[i, 1] = r1
        hit[1, i] = (r0 != q0) | (r1 != q1)
    return -1


@njit(nogil=True)
def before_product(A: np.ndarray, r_prev: np.ndarray, kc: np.ndarray, perm: np.ndarray, kappa_s: np.ndarray,
                   t_mean_s: np.ndarray, normals: np.ndarray, noise_on: bool, n: int, k: int, Z: np.ndarray,
                   a_out: np.ndarray, r_out: np.ndarray, hit: np.ndarray) -> None:
    """The vector environment's :func:`limit_commands` and its plant product's input columns
    ``n ..`` in slot order (sub-environment ``perm[s]`` in row ``s``): the applied rate
    commands, the mean wind torques and, with ``noise_on``, the gust normals scaled by the
    direction factors.

    :param A: finite actions ``(N, 2)`` float64 (:func:`dss14_env.envs.core.as_actions`)
    :param kappa_s: direction factors ``(2, N)`` and ``t_mean_s`` mean torques ``(2, N)``, in
        slot order
    :param normals: this step's standard normals ``(N, >= k)``, the gust's first
    :param Z: the product's input ``(N, n + 4 + 2 k)``, one row per slot
    """
    limit_commands(A, r_prev, kc, a_out, r_out, hit)
    N = A.shape[0]
    for s in range(N):
        i = perm[s]
        Z[s, n] = r_out[i, 0]
        Z[s, n + 1] = r_out[i, 1]
        Z[s, n + 2] = t_mean_s[0, s]
        Z[s, n + 3] = t_mean_s[1, s]
        if noise_on:
            ka, ke = kappa_s[0, s], kappa_s[1, s]
            for m in range(k):
                Z[s, n + 4 + m] = normals[i, m] * ka
                Z[s, n + 4 + k + m] = normals[i, m] * ke


@njit(nogil=True)
def after_product(Y: np.ndarray, y0: int, inv: np.ndarray, C: np.ndarray, CD: np.ndarray, NZ: np.ndarray,
                  j: int, episode: np.ndarray, a: np.ndarray, a_prev: np.ndarray, em_prev: np.ndarray,
                  r: np.ndarray, hit: np.ndarray, hits: np.ndarray, kc: np.ndarray, clamp_always: bool,
                  obs: np.ndarray, em: np.ndarray, out: np.ndarray) -> int:
    """Everything of a step after the plant product, for every sub-environment: encoders,
    servo and pointing errors, episode end, reward, observation (float32), the info values and
    the limiter hit counts.

    :param Y: the product's output rows in slot order, sub-environment ``i`` in row ``inv[i]``,
        with the step outputs in the columns ``y0 .. y0 + 3`` (encoder angles az, el; pointing
        angles el, xel; rad)
    :param C: commands at the step's end ``(T, N, 2)``, rad, of which ``C[j]`` is this step's;
        ``CD`` their rates (rad/s), ``NZ`` the encoder noise (rad; read only with encoder
        noise, :data:`NO_NOISE` without)
    :param episode: per sub-environment ``[start_az, start_el, max_error, wind_speed,
        wind_direction]`` ``(N, 5)``: absolute start position (rad), servo error bound (mdeg),
        mean wind (m/s, rad)
    :param a: clipped actions ``(N, 2)``, ``a_prev`` the previous ones; ``em_prev`` the previous
        measured errors (mdeg); ``r`` the applied rate commands (rad/s)
    :param hit: :func:`limit_commands`'s flags ``(2, N)``; ``hits`` the episodes' limiter hit
        counts ``(N, 2)`` (floats: whole numbers), advanced by them when every reward is finite
    :param clamp_always: clamp the observation's errors whether or not a sub-environment
        terminated (:meth:`~dss14_env.envs.core.StepConstants.clamp_always`)
    :param obs: receives the observations' first 12 entries ``(N, >= 12)`` float32, ``em`` the
        measured errors ``(N, 2)`` (the next step's ``em_prev``), ``out`` the rows
        ``(OUT_ROWS, N)``: :data:`INFO_FLOAT_ROWS`, reward, terminated, :data:`INFO_INT_ROWS`
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
        th0, th1 = Y[s, y0], Y[s, y0 + 1]
        s0, s1 = episode[i, 0], episode[i, 1]
        # encoders: the absolute angle (plus noise), rounded to the nearest count
        x0 = s0 + th0
        x1 = s1 + th1
        if sigma != 0.0:
            x0 += NZ[j, i, 0]
            x1 += NZ[j, i, 1]
        if quantum != 0.0:  # (np.floor: a float, NaN for NaN, compiled or not)
            x0 = np.floor(x0 * inv_q + 0.5) * quantum
            x1 = np.floor(x1 * inv_q + 0.5) * quantum
        rel0 = x0 - s0
        rel1 = x1 - s1
        # servo errors, measured and true
        c0, c1 = C[j, i, 0], C[j, i, 1]
        em0 = (c0 - rel0) * R2MD
        em1 = (c1 - rel1) * R2MD
        e0 = (c0 - th0) * R2MD
        e1 = (c1 - th1) * R2MD
        em[i, 0] = em0
        em[i, 1] = em1
        # episode end: an error beyond the bound, or outside the travel
        el = s1 + th1
        az_off = (s0 - az_centre) + th0
        me = episode[i, 2]
        t = (abs(e0) > me) | (abs(e1) > me) | (el < el_lo) | (el > el_hi) | (abs(az_off) > az_h)
        out[TERMINATED_ROW, i] = t
        any_term |= t
        # pointing errors
        pe0 = (c1 - Y[s, y0 + 2]) * R2MD
        pe1 = (c0 * xel - Y[s, y0 + 3]) * R2MD
        # reward: the scored errors and the action change, the penalty where terminated
        q0, q1 = (pe0, pe1) if pointing else (e0, e1)
        d0 = a[i, 0] - a_prev[i, 0]
        d1 = a[i, 1] - a_prev[i, 1]
        cost = (q0 * q0 + q1 * q1) * inv_es2 + w * (d0 * d0 + d1 * d1)
        if t:
            cost += penalty
        out[REWARD_ROW, i] = -cost
        total += cost
        # observation (layout OBS); the errors and error rates clamped below
        obs[i, 0] = em0 * inv_es
        obs[i, 1] = em1 * inv_es
        obs[i, 2] = (em0 - em_prev[i, 0]) * rate_scale
        obs[i, 3] = (em1 - em_prev[i, 1]) * rate_scale
        obs[i, 4] = c0 * R2D
        obs[i, 5] = c1 * R2D
        obs[i, 6] = CD[j, i, 0] * inv_rl
        obs[i, 7] = CD[j, i, 1] * inv_rl
        obs[i, 8] = rel0 * R2D
        obs[i, 9] = rel1 * R2D
        obs[i, 10] = r[i, 0] * inv_rl
        obs[i, 11] = r[i, 1] * inv_rl
        # info
        out[0, i] = e0
        out[1, i] = e1
        out[2, i] = em0
        out[3, i] = em1
        out[4, i] = pe0
        out[5, i] = pe1
        out[6, i] = episode[i, 3]
        out[7, i] = episode[i, 4]
        out[8, i] = r[i, 0] * R2D
        out[9, i] = r[i, 1] * R2D
    if any_term or clamp_always:  # clamped from the unrounded values
        for i in range(N):
            obs[i, 0] = _clamped(em[i, 0] * inv_es, OBS_ERROR_BOUND)
            obs[i, 1] = _clamped(em[i, 1] * inv_es, OBS_ERROR_BOUND)
            obs[i, 2] = _clamped((em[i, 0] - em_prev[i, 0]) * rate_scale, OBS_ERROR_RATE_BOUND)
            obs[i, 3] = _clamped((em[i, 1] - em_prev[i, 1]) * rate_scale, OBS_ERROR_RATE_BOUND)
    if not math.isfinite(total):  # NaN or infinite: some reward is
        return ANY_TERMINATED * any_term + NON_FINITE
    for i in range(N):
        hits[i, 0] += hit[0, i]
        hits[i, 1] += hit[1, i]
        out[OUT_ROWS - 2, i] = hits[i, 0]
        out[OUT_ROWS - 1, i] = hits[i, 1]
    return ANY_TERMINATED * any_term


# ------------------------------------------------------------------ the single environment (N = 1)
# Its step state, constants and outputs are one float vector (:func:`pack_one`): the loops above
# run on views of it made inside the compiled code, so that a step makes two calls of four and
# five arguments (each argument costs the call some 0.1 us to check and unpack).  The views have
# the types the vector environment's arrays have, so that each loop is compiled once.
_FIELDS = (("kc", _N_CONSTANTS), ("episode", 5), ("r_prev", 2), ("a_prev", 2), ("em_prev", 2), ("a", 2),
           ("em", 2), ("hits", 2), ("hit", 2), ("out", OUT_ROWS), ("clamp", 1))
_AT = dict(zip([f for f, _ in _FIELDS], np.cumsum([0] + [n for _, n in _FIELDS]).tolist(), strict=False))
(_KC, _EPISODE, _R_PREV, _A_PREV, _EM_PREV, _A, _EM, _HITS, _HIT, _OUT, _CLAMP) = (_AT[f] for f, _ in _FIELDS)
#: the length of :func:`pack_one`'s vector
ONE_SIZE = _CLAMP + 1
#: where :func:`pack_one`'s vector holds the episode's hit counts, and what the step tells: the
#: limiter's flags (rate, acceleration) and the ``out`` rows
ONE_HITS, ONE_INFO = slice(_HITS, _HITS + 2), slice(_HIT, _OUT + OUT_ROWS)


def pack_one(kc: np.ndarray, episode: np.ndarray, state: StepState, clamp_always: bool) -> np.ndarray:
    """The single environment's vector: constants :func:`constants`, :func:`episode_rows` ``(1, 5)``,
    the step state of :func:`reset_state` (N = 1) and whether every step clamps.
    """
    S = np.zeros(ONE_SIZE)
    S[_KC:_KC + _N_CONSTANTS], S[_EPISODE:_EPISODE + 5] = kc, episode[0]
    for at, v in ((_R_PREV, state.r_prev), (_A_PREV, state.a_prev), (_EM_PREV, state.em_prev),
                  (_HITS, state.hits)):
        S[at:at + 2] = v[0]
    S[_CLAMP] = clamp_always
    return S


@njit(nogil=True)
def limit_one(A: np.ndarray, B: np.ndarray, j: int, S: np.ndarray) -> int:
    """:func:`limit_commands` of the single environment: the action ``A`` ``(2,)`` (float32 or
    float64), its state vector ``S`` (:func:`pack_one`), the rate command written into row ``j``
    of its step block ``B`` (:func:`dss14_env.envs.plant.step_block`), the plant map's input.
    """
    a = np.empty((1, 2))
    a[0, 0], a[0, 1] = A[0], A[1]
    return limit_commands(a, S[_R_PREV:_R_PREV + 2].reshape((1, 2)), S[_KC:_KC + _N_CONSTANTS],
                          S[_A:_A + 2].reshape((1, 2)), B[j, 0:2].reshape((1, 2)),
                          S[_HIT:_HIT + 2].reshape((2, 1)))


@njit(nogil=True)
def after_one(B: np.ndarray, j: int, R: np.ndarray, S: np.ndarray, obs: np.ndarray) -> int:
    """:func:`after_product` of the single environment, after the plant map wrote row ``j + 1`` of
    its step block ``B``: the step's rows ``R`` ``(3, T, 1, 2)`` (command, its rate, encoder
    noise: :func:`dss14_env.envs.scenarios.block_rows`), its vector ``S`` (:func:`pack_one`: the outputs
    into its ``out`` rows, the state advanced unless a reward is not finite), the observation
    into ``obs`` ``(>= 12,)``.
    """
    flags = after_product(B[j + 1].reshape((1, B.shape[1])), B.shape[1] - N_STEP_OUTPUTS,
                          np.zeros(1, np.int64), R[0], R[1], R[2], j,
                          S[_EPISODE:_EPISODE + 5].reshape((1, 5)), S[_A:_A + 2].reshape((1, 2)),
                          S[_A_PREV:_A_PREV + 2].reshape((1, 2)), S[_EM_PREV:_EM_PREV + 2].reshape((1, 2)),
                          B[j, 0:2].reshape((1, 2)), S[_HIT:_HIT + 2].reshape((2, 1)),
                          S[_HITS:_HITS + 2].reshape((1, 2)), S[_KC:_KC + _N_CONSTANTS], S[_CLAMP] != 0.0,
                          obs.reshape((1, obs.size)), S[_EM:_EM + 2].reshape((1, 2)),
                          S[_OUT:_OUT + OUT_ROWS].reshape((OUT_ROWS, 1)))
    if not flags & NON_FINITE:
        for m in range(2):
            S[_R_PREV + m] = B[j, m]
            S[_A_PREV + m] = S[_A + m]
            S[_EM_PREV + m] = S[_EM + m]
    return flags


def step_outputs(n: int, width: int = OBS_SIZE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fresh output arrays of :func:`after_product` for ``n`` sub-environments:
    ``(obs (n, width) float32, em (n, 2), out (OUT_ROWS, n))``.
    """
    return np.empty((n, width), np.float32), np.empty((n, 2)), np.empty((OUT_ROWS, n))


def episode_rows(start: np.ndarray, max_error: np.ndarray, wind: np.ndarray) -> np.ndarray:
    """:func:`after_product`'s per-episode constants ``(N, 5)``: ``[start (2), max_error,
    wind (2)]`` (rad, mdeg, m/s and rad).
    """
    return np.column_stack((start, max_error, wind))


def reset_state(c: np.ndarray, cd: np.ndarray, y: np.ndarray, noise: np.ndarray, r0: np.ndarray,
                episode: np.ndarray, kc: np.ndarray, k: StepConstants, width: int = OBS_SIZE
                ) -> tuple[StepState, np.ndarray, dict[str, np.ndarray]]:
    """The reset, for both environments: the step state, first observation and reset info (keys
    :data:`dss14_env.envs.core.RESET_INFO_KEYS`) of freshly drawn episodes, one row each, made by
    :func:`after_product` (errors and observation clamped; the error rates 0: no step before).

    :param c: commands at t = 0 relative to the start ``(N, 2)``, rad; ``cd`` their rates, rad/s
    :param y: plant outputs at t = 0 ``(N, >= 4)``: encoder angles, pointing angles (rad)
    :param noise: encoder noise of the reading at t = 0 ``(N, 2)``, rad
    :param r0: the rate commands that hold the start motion ``(N, 2)``, rad/s (clipped to the
        rate limit here: the previous applied rate command)
    :param episode: :func:`episode_rows`; ``kc`` :func:`constants` of ``k``
    :param width: the observation's width (12, or 14 with the monopulse sensor: its entries are
        the caller's)
    """
    n = c.shape[0]
    rp = np.clip(r0, -k.rate_limit, k.rate_limit)
    a0 = np.clip(rp / k.action_scale, -1.0, 1.0)  # the action that reproduces rp
    obs, em, out = step_outputs(n, width)
    hits = np.zeros((n, 2))
    after_product(y, 0, np.arange(n), c[None], cd[None], noise[None], 0, episode,
                  a0, a0, np.zeros((n, 2)), rp, np.zeros((2, n)), hits, kc, True, obs, em, out)
    obs[:, 2:4] = 0.0
    info = dict(zip(INFO_FLOAT_ROWS, out, strict=False))
    state = StepState(rp, a0, em, hits, np.zeros(n, np.int64))
    return state, obs, {key: info[key] for key in RESET_INFO_KEYS}


def info_arrays(out: np.ndarray, actions: np.ndarray, hit: np.ndarray) -> dict[str, Any]:
    """The vector environment's step info (keys :data:`dss14_env.envs.core.INFO_KEYS`, in order)
    from :func:`after_product`'s ``out`` and :func:`limit_commands`'s ``hit``: arrays ``(N,)``
    (``action_unclipped`` ``(N, 2)``: the actions as given).
    """
    counts = out[OUT_ROWS - 2:].astype(np.int64)
    return {**dict(zip(INFO_FLOAT_ROWS[:8], out[:8], strict=True)), "action_unclipped": actions,
            "rate_command_az_deg_s": out[8], "rate_command_el_deg_s": out[9],
            "rate_limited": hit[0] != 0.0, "accel_limited": hit[1] != 0.0,
            "n_rate_limited": counts[0], "n_accel_limited": counts[1]}
