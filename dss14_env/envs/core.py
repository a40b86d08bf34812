"""The step of the DSS14 environments, once: input checks, command limiter, encoders, servo and
pointing errors, episode end, reward, observation and info.

FuncEnv-style: the step's dynamic state is one typed :class:`StepState` (previous rate command,
action and measured error, limiter hit counts, noise-block row); :func:`reset_state` makes it
with the first observation and info (both environments reset through it), each step maps it
to the next.  The observation's layout is named once (:data:`OBS`, :class:`ObsLayout`).

Every piece is a function of ``(N, ...)`` numpy arrays (N sub-environments); the vector
environment (:mod:`dss14_env.envs.vector`) calls them.  The single environment
(:mod:`dss14_env.envs.env`) runs one step in a few microseconds, where a numpy call costs about
one, so it calls the *scalar twin* :func:`step_1` (the same formulas on Python floats, in the
same order of operations; the reward's cost is the very function the batched piece calls,
:func:`step_cost`, which takes floats or arrays, and the episode end is the rule of
:func:`beyond_bounds` in its short-circuit form on floats).
``tests/test_env_core.py`` holds the twin equal to the batched pieces, bit for bit, on random
inputs (hypothesis), limiter edges, quantisation and termination boundaries and clamping
included.

The pieces, in the order of a step (SI inside; mdeg and deg at the interface)::

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
>>> from dss14_env.envs.config import load_env_config
>>> k = StepConstants.from_config(load_env_config())
>>> a, r, rate_hit, acc_hit = limit_commands(np.array([[2.0, -0.01]]), np.zeros((1, 2)), k)
>>> a.tolist(), (r * R2D).round(6).tolist(), acc_hit.tolist()
([[1.0, -0.01]], [[0.004, -0.0025]], [True])
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from dss14_env.core.units import DEG, MDEG, R2D, R2MD
from dss14_env.envs.config import EnvConfig


class ObsLayout(NamedTuple):
    """The observation's layout, named once: each field is the slice ``[az, el]`` of its pair of
    entries (the table in :class:`dss14_env.envs.env.DSS14Env`).

    >>> OBS.prev_rate, OBS.entries("error", "prev_rate")
    (slice(10, 12, None), (0, 1, 10, 11))
    """

    #: measured servo error, ``error_scale_mdeg``
    error: slice
    #: servo-error rate, ``error_scale_mdeg`` per s
    error_rate: slice
    #: commanded position relative to the start, deg
    command: slice
    #: commanded rate, ``rate_limit_deg_s``
    command_rate: slice
    #: encoder reading relative to the start, deg
    encoder: slice
    #: previous applied rate command (limiter output), ``rate_limit_deg_s``
    prev_rate: slice

    def entries(self, *names: str) -> tuple[int, ...]:
        """The indices of the named pairs' entries, in the order given.

        :raises ValueError: an unknown name
        """
        bad = [n for n in names if n not in self._fields]
        if bad:
            raise ValueError(f"observation entries must be named from {', '.join(self._fields)}, "
                             f"got {bad[0]!r}")
        return tuple(i for n in names for i in range(getattr(self, n).start, getattr(self, n).stop))


#: the observation layout (:class:`ObsLayout`)
OBS = ObsLayout(*(slice(2 * i, 2 * i + 2) for i in range(len(ObsLayout._fields))))
#: number of observation entries
OBS_SIZE = 2 * len(ObsLayout._fields)
#: observation names, in order (``<pair>_az``, ``<pair>_el``)
OBS_NAMES = tuple(f"{pair}_{axis}" for pair in ObsLayout._fields for axis in ("az", "el"))
#: bounds of the observation (see the table in DSS14Env); errors and error rates are clamped to
#: them, which without encoder noise can only act on a terminating step
OBS_ERROR_BOUND = 1.0e4
OBS_ERROR_RATE_BOUND = 1.0e6
OBS_POSITION_BOUND_DEG = 720.0
_BOUNDS = {"error": OBS_ERROR_BOUND, "error_rate": OBS_ERROR_RATE_BOUND, "command": OBS_POSITION_BOUND_DEG,
           "command_rate": 1.0, "encoder": OBS_POSITION_BOUND_DEG, "prev_rate": 1.0}
OBS_HIGH = np.array([_BOUNDS[pair] for pair in ObsLayout._fields for _ in range(2)], dtype=np.float32)
#: the batched observation's pair indices (:func:`observation` builds it pair-major)
_N_PAIRS = len(ObsLayout._fields)
_P_ERROR, _P_RATE, _P_COMMAND, _P_COMMAND_RATE, _P_ENCODER, _P_PREV_RATE = (
    getattr(OBS, name).start // 2 for name in ObsLayout._fields)
#: the clamped pairs (errors and error rates) and their bounds, one per pair
_P_CLAMPED = slice(_P_ERROR, _P_RATE + 1)
_PAIR_BOUNDS = OBS_HIGH[OBS.error.start:OBS.error_rate.stop:2, None, None].astype(np.float64)
#: the info keys of every step, in order
INFO_KEYS = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg",
             "measured_error_el_mdeg", "pointing_error_el_mdeg", "pointing_error_xel_mdeg",
             "wind_speed_mps", "wind_direction_rad", "action_unclipped", "rate_command_az_deg_s",
             "rate_command_el_deg_s", "rate_limited", "accel_limited", "n_rate_limited",
             "n_accel_limited")


@dataclass(frozen=True)
class StepConstants:
    """The configuration's constants of a step, in SI (built by :meth:`from_config`).

    :param dt: control period, s
    :param action_scale: rate command at action 1, rad/s
    :param rate_limit: rate-command clip, rad/s
    :param rate_step: largest change of the rate command per step, rad/s
    :param rate_clip: the rate clip can act (``action_scale > rate_limit``)
    :param quantum: encoder count, rad (0: exact readings)
    :param encoder_sigma: encoder noise std, rad
    :param error_scale: observation unit of the servo errors, mdeg
    :param action_change_weight: weight of ``||a - a_prev||^2`` in the cost
    :param termination_penalty: extra cost of the terminating step
    :param el_limits: elevation travel ``(low, high)``, rad
    :param az_centre: azimuth cable-wrap centre, rad
    :param az_half_range: azimuth travel about the centre, rad
    :param pointing_reward: the reward scores the pointing errors (``reward: pointing``), not
        the servo errors
    """

    dt: float
    action_scale: float
    rate_limit: float
    rate_step: float
    rate_clip: bool
    quantum: float
    encoder_sigma: float
    error_scale: float
    action_change_weight: float
    termination_penalty: float
    el_limits: tuple[float, float]
    az_centre: float
    az_half_range: float
    pointing_reward: bool = False

    @classmethod
    def from_config(cls, c: EnvConfig) -> StepConstants:
        """The constants of a checked configuration."""
        scale, rl = c.action_scale_deg_s * DEG, c.rate_limit_deg_s * DEG
        return cls(c.dt, scale, rl, c.accel_limit_deg_s2 * DEG * c.dt, scale > rl,
                   (2.0 * math.pi / 2 ** c.encoder_bits) if c.encoder_bits else 0.0,
                   c.encoder_noise_mdeg * MDEG, c.error_scale_mdeg, c.action_change_weight,
                   c.termination_penalty, (c.el_limits_deg[0] * DEG, c.el_limits_deg[1] * DEG),
                   c.az_wrap_centre_deg * DEG, c.az_wrap_half_range_deg * DEG, c.reward == "pointing")

    @property
    def inv_quantum(self) -> float:
        """``1 / quantum`` (0 for exact readings)."""
        return 1.0 / self.quantum if self.quantum else 0.0

    @property
    def inv_error_scale(self) -> float:
        return 1.0 / self.error_scale

    @property
    def error_rate_scale(self) -> float:
        """Observation factor of the error difference of one step: ``1 / (error_scale dt)``."""
        return (1.0 / self.error_scale) * (1.0 / self.dt)

    @property
    def inv_rate_limit(self) -> float:
        return 1.0 / self.rate_limit

    def clamp_always(self, max_error_mdeg: float) -> bool:
        """Whether the observation bounds can be passed without terminating (encoder noise, or
        bounds tighter than the error bound plus one count): then every step clamps.
        """
        me_q = max_error_mdeg + self.quantum * R2MD
        return (bool(self.encoder_sigma) or me_q / self.error_scale > OBS_ERROR_BOUND
                or 2.0 * me_q * self.error_rate_scale > OBS_ERROR_RATE_BOUND)


# ------------------------------------------------------------------------------ input checks
def _describe(x: Any) -> str:
    text = repr(x)
    return text if len(text) <= 80 else text[:77] + "..."


def as_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """The action(s) as a new float64 array of ``shape``, checked.

    Accepted: real numbers (bool, complex, strings and objects are not), of the given shape,
    all finite.

    :raises ValueError: ``action must be ...``, naming what was wrong
    """
    try:
        a = np.asarray(actions)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"action must be an array of real numbers of shape {shape}, got "
                         f"{_describe(actions)}") from None
    if a.dtype.kind not in "iuf":
        raise ValueError(f"action must be an array of real numbers of shape {shape}, got dtype "
                         f"{a.dtype}: {_describe(actions)}")
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape}, got shape {a.shape}")
    if a.dtype.itemsize > 8:  # longdouble: may overflow float64
        with np.errstate(over="ignore"):
            a = a.astype(np.float64)
    else:
        a = a.astype(np.float64)
    if not np.isfinite(a).all():
        bad = np.flatnonzero(~np.isfinite(a).reshape(a.shape[0] if a.ndim > 1 else 1, -1).all(axis=1))
        where = f" (sub-environment(s) {bad.tolist()})" if a.ndim > 1 else ""
        raise ValueError(f"action must be finite, got {_describe(a.tolist())}{where}")
    return a


def check_seed(seed: Any) -> int | None:
    """``seed``: None or a non-negative integer (Python or numpy); returned as ``int``.

    :raises ValueError: ``seed must be ...``
    """
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be None or a non-negative integer, got {_describe(seed)}")
    return int(seed)


def check_seeds(seed: Any, n: int) -> list[int | None]:
    """The seeds of ``n`` sub-environments: ``seed + i`` for an integer, the entries of a
    sequence of ``n`` seeds, or ``n`` times None.

    :raises ValueError: ``seed must be ...``
    """
    if seed is None:
        return [None] * n
    if isinstance(seed, (list, tuple, np.ndarray)):
        if len(seed) != n:
            raise ValueError(f"seed must be None, a non-negative integer or a sequence of num_envs = {n} "
                             f"seeds, got a sequence of {len(seed)}")
        return [check_seed(s) for s in seed]
    try:
        s = check_seed(seed)
    except ValueError:
        raise ValueError(f"seed must be None, a non-negative integer or a sequence of num_envs = {n} "
                         f"seeds, got {_describe(seed)}") from None
    return [s + i for i in range(n)]  # type: ignore[operator]


# ------------------------------------------------------------------------------ batched pieces
def limit_commands(a: np.ndarray, r_prev: np.ndarray, k: StepConstants
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The command limiter.

    :param a: actions ``(N, 2)`` (finite)
    :param r_prev: previous applied rate commands ``(N, 2)``, rad/s
    :return: ``(a_clipped, r, rate_hit, acc_hit)``: the actions clipped to [-1, 1], the applied
        rate commands (rad/s), and per row whether the rate clip / acceleration limit acted
    """
    # clip(x, lo, hi) = minimum(maximum(x, lo), hi), as np.clip, without its Python wrapper
    c = np.maximum(a, -1.0)
    np.minimum(c, 1.0, out=c)
    q = c * k.action_scale
    if k.rate_clip:
        hit = np.abs(q) > k.rate_limit
        rate_hit = hit[:, 0] | hit[:, 1]
        np.maximum(q, -k.rate_limit, out=q)
        np.minimum(q, k.rate_limit, out=q)
    else:
        rate_hit = np.zeros(a.shape[0], bool)
    r = np.maximum(q, r_prev - k.rate_step)
    np.minimum(r, r_prev + k.rate_step, out=r)
    hit = r != q
    return c, r, rate_hit, hit[:, 0] | hit[:, 1]


def start_action(r0: np.ndarray, k: StepConstants) -> np.ndarray:
    """The action ``a[-1]`` before the first step: the one that reproduces the start rate
    command ``r0`` (rad/s), clipped to [-1, 1] as every action is.
    """
    return np.clip(r0 / k.action_scale, -1.0, 1.0)


def quantise(angle: np.ndarray, quantum: float) -> np.ndarray:
    """Round absolute angles (rad) to the nearest encoder count (``quantum`` 0: unchanged)."""
    if not quantum:
        return np.array(angle, float)
    x = angle * (1.0 / quantum)
    x += 0.5
    np.floor(x, out=x)
    x *= quantum
    return x


def read_encoders(theta: np.ndarray, start: np.ndarray, noise: np.ndarray | None, k: StepConstants
                  ) -> np.ndarray:
    """Encoder readings relative to the start, rad: the absolute angle ``start + theta`` plus
    the noise, quantised.

    :param theta: encoder angles relative to the start ``(N, 2)``, rad (plant outputs)
    :param start: absolute start positions ``(N, 2)``, rad
    :param noise: encoder noise ``(N, 2)``, rad (ignored without ``encoder_sigma``)
    """
    a = start + theta
    if k.encoder_sigma:
        a += noise
    a = quantise(a, k.quantum) if k.quantum else a
    a -= start
    return a


def servo_errors(c: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Servo errors ``c - theta`` in mdeg (true with plant angles, measured with readings)."""
    d = c - theta
    d *= R2MD
    return d


def terminated(e: np.ndarray, theta: np.ndarray, start: np.ndarray, max_error: np.ndarray | float,
               k: StepConstants) -> np.ndarray:
    """Episode end: the true servo error beyond ``max_error`` (mdeg; per row or one) on an axis,
    or the antenna outside its travel (elevation limits, azimuth half-range about the wrap
    centre).

    :return: ``(N,)`` bool
    """
    el = start[:, 1] + theta[:, 1]
    az_off = (start[:, 0] - k.az_centre) + theta[:, 0]
    return beyond_bounds(e[:, 0], e[:, 1], el, az_off, np.asarray(max_error), k.el_limits[0], k.el_limits[1],
                         k.az_half_range)


def beyond_bounds(e_az: Any, e_el: Any, el: Any, az_off: Any, max_error: Any, el_lo: float, el_hi: float,
                  az_half_range: float) -> Any:
    """The episode-end rule: a servo error beyond ``max_error`` (mdeg) on an axis, the elevation
    outside ``[el_lo, el_hi]`` or the azimuth beyond ``az_half_range`` of the wrap centre
    (``az_off``; rad).  Takes floats or arrays; the scalar step (:func:`step_1`) writes the
    same comparisons joined by ``or`` (``|`` on two Python bools costs as much as the
    comparisons), held equal to this by ``tests/test_env_core.py``.
    """
    return ((abs(e_az) > max_error) | (abs(e_el) > max_error) | (el < el_lo) | (el > el_hi)
            | (abs(az_off) > az_half_range))


def step_cost(s0: Any, s1: Any, d0: Any, d1: Any, inv_scale2: float, weight: float) -> Any:
    """The cost (minus the reward) before the termination penalty, written once for floats and
    arrays: ``(s0^2 + s1^2) inv_scale2 + weight (d0^2 + d1^2)``; the callers add the penalty
    where the step terminates (:func:`reward`; :func:`step_1` only then: adding ``0.0`` to
    the non-negative cost changes no bit).

    :param s0: the scored errors (mdeg; :func:`scored_errors`), ``s1`` the other axis
    :param d0: the action changes ``a - a_prev``, ``d1`` the other axis
    :param inv_scale2: ``1 / error_scale^2``
    """
    return (s0 * s0 + s1 * s1) * inv_scale2 + weight * (d0 * d0 + d1 * d1)


def reward(e: np.ndarray, a: np.ndarray, a_prev: np.ndarray, term: np.ndarray, k: StepConstants
           ) -> np.ndarray:
    """``-((e_1^2 + e_2^2) / error_scale^2 + w ||a - a_prev||^2)``, less the termination
    penalty where ``term``.

    :param e: the scored errors ``(N, 2)``, mdeg: the true servo errors ``[az, el]``, or the
        pointing errors ``[el, xel]`` with ``k.pointing_reward`` (:func:`scored_errors`)
    :param a: clipped actions ``(N, 2)``; ``a_prev`` the previous ones
    """
    d = a - a_prev
    cost = step_cost(e[:, 0], e[:, 1], d[:, 0], d[:, 1], k.inv_error_scale * k.inv_error_scale,
                     k.action_change_weight)
    cost += term * k.termination_penalty
    return np.negative(cost, out=cost)


def scored_errors(e: np.ndarray, pe: np.ndarray, k: StepConstants) -> np.ndarray:
    """The errors the reward scores: the true servo errors ``e`` or, with
    ``k.pointing_reward``, the pointing errors ``pe`` (:func:`pointing_errors`), mdeg.
    """
    return pe if k.pointing_reward else e


def observation(em: np.ndarray, em_prev: np.ndarray | None, c_deg: np.ndarray, cd_scaled: np.ndarray,
                rel: np.ndarray, r: np.ndarray, clamp: bool, k: StepConstants) -> np.ndarray:
    """The observation ``(N, 12)`` float32 (layout :data:`OBS_NAMES`).

    :param em: measured servo errors ``(N, 2)``, mdeg; ``em_prev`` those of the step before
        (None at a reset: error rates 0)
    :param c_deg: commanded positions relative to the start, deg
    :param cd_scaled: commanded rates in units of the rate limit
    :param rel: encoder readings relative to the start, rad
    :param r: applied rate commands, rad/s
    :param clamp: clamp the errors and error rates to their bounds
    """
    n = em.shape[0]
    o = np.empty((_N_PAIRS, n, 2))  # pair-major, float64: each pair one contiguous (N, 2) block
    np.multiply(em, 1.0 / k.error_scale, out=o[_P_ERROR])
    if em_prev is None:
        o[_P_RATE] = 0.0
    else:
        np.subtract(em, em_prev, out=o[_P_RATE])
        o[_P_RATE] *= k.error_rate_scale
    if clamp:
        np.maximum(o[_P_CLAMPED], -_PAIR_BOUNDS, out=o[_P_CLAMPED])
        np.minimum(o[_P_CLAMPED], _PAIR_BOUNDS, out=o[_P_CLAMPED])
    o[_P_COMMAND] = c_deg
    o[_P_COMMAND_RATE] = cd_scaled
    np.multiply(rel, R2D, out=o[_P_ENCODER])
    np.multiply(r, 1.0 / k.rate_limit, out=o[_P_PREV_RATE])
    o32 = o.astype(np.float32)  # each entry rounded once, from float64
    # (pairs, N, 2) -> (N, pairs, 2), each pair moved as one 8-byte item (a transposing copy
    # of single floats goes entry by entry, several times slower)
    return np.ascontiguousarray(o32.view(np.complex64)[..., 0].T).view(np.float32).reshape(n, OBS_SIZE)


def pointing_errors(c: np.ndarray, point: np.ndarray, xel_scale: float) -> np.ndarray:
    """The dish's pointing errors ``[el, xel]`` in mdeg: the command less the structure's
    pointing angles (deformation included); the cross-elevation command is the azimuth command
    times ``xel_scale = cos(E)``, as in the structure model's xel output.

    :param c: commands ``[az, el]`` relative to the start ``(N, 2)``, rad
    :param point: pointing outputs ``[point_el, point_xel]`` ``(N, 2)``, rad
    """
    out = np.empty_like(point)
    np.subtract(c[:, 1], point[:, 0], out=out[:, 0])
    np.multiply(c[:, 0], xel_scale, out=out[:, 1])
    out[:, 1] -= point[:, 1]
    out *= R2MD
    return out


def step_info(e: np.ndarray, em: np.ndarray, pe: np.ndarray, wind: np.ndarray, a_raw: np.ndarray,
              r: np.ndarray, rate_hit: np.ndarray, acc_hit: np.ndarray, hits: np.ndarray) -> dict[str, Any]:
    """The info of a step (keys :data:`INFO_KEYS`), arrays of shape ``(N,)`` (``action_unclipped``
    ``(N, 2)``).

    :param e: true servo errors (mdeg); ``em`` measured
    :param pe: pointing errors ``[el, xel]`` (mdeg, :func:`pointing_errors`)
    :param wind: ``[speed (m/s), direction (rad)]`` per row
    :param a_raw: the actions as given
    :param r: applied rate commands, rad/s
    :param rate_hit: the rate clip acted; ``acc_hit`` the acceleration limit
    :param hits: the episode's limiter hit counts ``[rate, accel]``
    """
    rd = r * R2D
    return {"servo_error_az_mdeg": e[:, 0], "servo_error_el_mdeg": e[:, 1],
            "measured_error_az_mdeg": em[:, 0].copy(), "measured_error_el_mdeg": em[:, 1].copy(),
            "pointing_error_el_mdeg": pe[:, 0].copy(), "pointing_error_xel_mdeg": pe[:, 1].copy(),
            "wind_speed_mps": wind[:, 0].copy(), "wind_direction_rad": wind[:, 1].copy(),
            "action_unclipped": a_raw, "rate_command_az_deg_s": rd[:, 0], "rate_command_el_deg_s": rd[:, 1],
            "rate_limited": rate_hit, "accel_limited": acc_hit,
            "n_rate_limited": hits[:, 0].copy(), "n_accel_limited": hits[:, 1].copy()}


# ------------------------------------------------------------------------------ state and reset
#: the reset-info keys of the first state, for both environments (both add the episode's:
#: :data:`dss14_env.envs.scenarios.EPISODE_INFO_KEYS`)
RESET_INFO_KEYS = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg",
                   "measured_error_el_mdeg", "pointing_error_el_mdeg", "pointing_error_xel_mdeg",
                   "wind_speed_mps", "wind_direction_rad", "rate_command_az_deg_s", "rate_command_el_deg_s")


class StepState(NamedTuple):
    """The dynamic state a step reads and writes besides the plant (FuncEnv-style:
    :func:`reset_state` makes it, a step maps it to the next one).

    Each field holds every sub-environment (arrays ``(N, 2)``, ``j`` ``(N,)``); the single
    environment's scalar step (:func:`step_1`) carries the same state flat, as a
    :class:`ScalarState`.  The plant state lives beside it in each environment's own layout
    (the single one's step buffers, the vector one's slot-ordered batch).
    """

    #: previous applied rate command ``[az, el]``, rad/s (the limiter's memory)
    r_prev: Any
    #: previous clipped action ``[az, el]`` (the reward's action change)
    a_prev: Any
    #: previous measured servo error ``[az, el]``, mdeg (the observed error rate)
    em_prev: Any
    #: the episode's limiter hit counts ``[rate, accel]``
    hits: Any
    #: the next step's row in its noise block
    j: Any


class ScalarState(NamedTuple):
    """The :class:`StepState` of one environment, flat, on Python floats and ints: what the
    scalar step (:func:`step_1`) reads and makes (one tuple per step, not five).
    """

    #: previous applied rate command, az and el, rad/s
    r_az: float
    r_el: float
    #: previous clipped action, az and el
    a_az: float
    a_el: float
    #: previous measured servo error, az and el, mdeg
    em_az: float
    em_el: float
    #: the episode's limiter hit counts: rate clip, acceleration limit
    n_rate: int
    n_acc: int
    #: the next step's row in its noise block
    j: int

    @classmethod
    def of(cls, st: StepState, j: int = 0) -> ScalarState:
        """Row 0 of a batched state (:func:`reset_state` with N = 1), at row ``j`` of its noise
        block.
        """
        return cls(*(x for v in st[:4] for x in v[0].tolist()), j)


def reset_state(c: np.ndarray, cd: np.ndarray, y: np.ndarray, start: np.ndarray, noise: np.ndarray,
                r0: np.ndarray, wind: np.ndarray, xel_scale: float, k: StepConstants
                ) -> tuple[StepState, np.ndarray, dict[str, np.ndarray]]:
    """The reset, written once for both environments: the step state, first observation and
    reset info (keys :data:`RESET_INFO_KEYS`) of freshly drawn episodes, one row each.

    :param c: commands at t = 0 relative to the start ``(N, 2)``, rad; ``cd`` their rates, rad/s
    :param y: plant outputs at t = 0 ``(N, >= 4)``: encoder angles, pointing angles (rad)
    :param start: absolute start positions ``(N, 2)``, rad
    :param noise: encoder noise of the reading at t = 0 ``(N, 2)``, rad
    :param r0: the rate commands that hold the start motion ``(N, 2)``, rad/s (clipped to the
        rate limit here: the previous applied rate command)
    :param wind: ``[speed (m/s), direction (rad)]`` per row
    :param xel_scale: as for :func:`pointing_errors`
    """
    rp = np.clip(r0, -k.rate_limit, k.rate_limit)
    theta = y[:, 0:2]
    rel = read_encoders(theta, start, noise, k)
    em, e = servo_errors(c, rel), servo_errors(c, theta)
    obs = observation(em, None, c * R2D, cd * (1.0 / k.rate_limit), rel, rp, True, k)
    n = c.shape[0]
    none, zeros = np.zeros(n, bool), np.zeros((n, 2), np.int64)
    info = step_info(e, em, pointing_errors(c, y[:, 2:4], xel_scale), wind, np.full((n, 2), np.nan), rp,
                     none, none, zeros)
    state = StepState(rp, start_action(rp, k), em, zeros, np.zeros(n, np.int64))
    return state, obs, {key: info[key] for key in RESET_INFO_KEYS}


# ------------------------------------------------------------------------------ scalar twin
# The single environment's step on Python floats: the pieces above in one function (a call
# costs as much as a piece here), in the same order of operations, so that the results are
# the same bit for bit; tests/test_env_core.py holds each of its results against the batched
# piece it replaces.  The reward's cost is the batched piece's own formula (:func:`step_cost`),
# called on floats; the episode end is :func:`beyond_bounds`'s rule joined by ``or``.
class EpisodeConstants(NamedTuple):
    """What the scalar step (:func:`step_1`) reads that is fixed for one episode
    (:func:`step_constants`; SI, errors in mdeg).
    """

    action_scale: float
    rate_clip: bool
    rate_limit: float
    rate_step: float
    start_az: float
    start_el: float
    quantum: float
    inv_quantum: float
    max_error: float
    az_offset: float
    el_lo: float
    el_hi: float
    az_half_range: float
    inv_error_scale2: float
    action_change_weight: float
    termination_penalty: float
    inv_error_scale: float
    error_rate_scale: float
    inv_rate_limit: float
    clamp_always: bool
    xel_scale: float
    wind_speed: float
    wind_direction: float
    pointing_reward: bool


def step_constants(k: StepConstants, start: tuple[float, float], max_error: float, xel_scale: float,
                   wind_speed: float, wind_direction: float) -> EpisodeConstants:
    """The constants of :func:`step_1` for one episode.

    :param start: absolute start position ``(az, el)``, rad
    :param max_error: servo error bound, mdeg (also decides whether every step clamps the
        observation, :meth:`StepConstants.clamp_always`)
    :param xel_scale: ``cos(E)`` of the structure model (:func:`pointing_errors`)
    :param wind_speed: the episode's mean wind, m/s; ``wind_direction`` its direction, rad
    """
    s_az, s_el = float(start[0]), float(start[1])
    return EpisodeConstants(
        k.action_scale, k.rate_clip, k.rate_limit, k.rate_step, s_az, s_el, k.quantum, k.inv_quantum,
        max_error, s_az - k.az_centre, k.el_limits[0], k.el_limits[1], k.az_half_range,
        k.inv_error_scale * k.inv_error_scale, k.action_change_weight, k.termination_penalty,
        k.inv_error_scale, k.error_rate_scale, k.inv_rate_limit, k.clamp_always(max_error), xel_scale,
        wind_speed, wind_direction, k.pointing_reward)


def _clamp(x: float, b: float) -> float:
    return b if x > b else (-b if x < -b else x)


_fromiter, _floor = np.fromiter, math.floor  # the hot path's names
_tuple_new = tuple.__new__  # a ScalarState without the NamedTuple constructor's call overhead


_F32, _F64 = np.dtype(np.float32), np.dtype(np.float64)


def step_1(action: Any, views: tuple, st: ScalarState, MT: np.ndarray, row: list, sc: EpisodeConstants
           ) -> tuple[tuple[np.ndarray, float, bool, bool, dict[str, Any]], ScalarState]:
    """One step of one environment on floats: :func:`as_actions` (a fast path for float32 and
    float64 arrays of shape (2,), the same rule), :func:`limit_commands`, the plant map
    (:meth:`dss14_env.envs.plant.Plant.episode_map`), :func:`read_encoders`, :func:`servo_errors`,
    :func:`terminated`, :func:`reward`, :func:`observation` and :func:`step_info` (with
    :func:`pointing_errors`).

    :param action: the action as given
    :param views: the step's views into the episode's step block
        (:func:`dss14_env.envs.plant.block_views`: its buffer, whose input holds the plant state
        and the step's gust noise, and where the product writes the next state and outputs)
    :param st: the :class:`ScalarState`
    :param MT: the episode's plant map (:meth:`dss14_env.envs.plant.Plant.episode_map`),
        transposed and C-contiguous (``input @ MT``: the fastest matrix-vector product here)
    :param row: the step's row ``[c_az, c_el, c_az_deg, c_el_deg, cd_az, cd_el, n_az, n_el]`` of
        :func:`dss14_env.envs.scenarios.block_rows`: command at the step's end (rad, deg), its
        rate in units of the rate limit, encoder noise (rad)
    :param sc: :func:`step_constants`
    :return: ``((obs, reward, terminated, False, info), st_next)``: the step's result as
        ``Env.step`` returns it (never truncated: the time limit is the wrapper's) and the next
        state
    :raises ValueError: a bad action (:func:`as_actions`), before anything changes
    :raises FloatingPointError: the plant state became non-finite (it left the range it is
        meant for)
    """
    try:  # fast path: a float32 or float64 array of two finite numbers
        dt = action.dtype
        a0, a1 = action.tolist() if dt is _F32 or dt is _F64 else (None, None)
        if type(a0) is not float or type(a1) is not float or a0 - a0 != 0.0 or a1 - a1 != 0.0:
            a0, a1 = as_actions(action, (2,)).tolist()  # x - x is NaN for NaN and +-inf
    except (AttributeError, TypeError, ValueError):
        a0, a1 = as_actions(action, (2,)).tolist()
    z, inp, out, y = views
    rp0, rp1, ap0, ap1, em0_az, em0_el, n_rate, n_acc, j = st
    (scale, rate_clip, rl, dr, s_az, s_el, quantum, inv_q, me, az_off0, el_lo, el_hi, az_h, inv_es2, w,
     penalty, inv_es, rate_scale, inv_rl, clamp_always, xel_scale, wind_speed, wind_direction, pointing) = sc
    # command limiter
    c0 = 1.0 if a0 > 1.0 else (-1.0 if a0 < -1.0 else a0)
    c1 = 1.0 if a1 > 1.0 else (-1.0 if a1 < -1.0 else a1)
    r0 = c0 * scale
    r1 = c1 * scale
    rate_hit = False
    if rate_clip and (r0 > rl or r0 < -rl or r1 > rl or r1 < -rl):
        rate_hit = True
        n_rate += 1
        r0 = rl if r0 > rl else (-rl if r0 < -rl else r0)
        r1 = rl if r1 > rl else (-rl if r1 < -rl else r1)
    acc_hit = False
    b = rp0 + dr
    if r0 > b:
        r0, acc_hit = b, True
    else:
        b = rp0 - dr
        if r0 < b:
            r0, acc_hit = b, True
    b = rp1 + dr
    if r1 > b:
        r1, acc_hit = b, True
    else:
        b = rp1 - dr
        if r1 < b:
            r1, acc_hit = b, True
    if acc_hit:
        n_acc += 1
    # the plant map: [u+, y+] = M [r, 1, xi, u], the exact discretisation (Plant.episode_map)
    z[0] = r0
    z[1] = r1
    inp.dot(MT, out)  # the method: no dispatch of np.dot
    c_az, c_el, c_deg_az, c_deg_el, cd_az, cd_el, n_az, n_el = row
    th_az, th_el, p_el, p_xel = y.tolist()
    # encoders (absolute angle, quantised) and servo errors
    if n_az or n_el:
        a_az, a_el = s_az + th_az + n_az, s_el + th_el + n_el
    else:
        a_az, a_el = s_az + th_az, s_el + th_el
    if quantum:
        try:
            a_az = quantum * _floor(a_az * inv_q + 0.5)
            a_el = quantum * _floor(a_el * inv_q + 0.5)
        except (ValueError, OverflowError):  # floor of NaN or inf: the reward's check below raises
            a_az = a_el = math.nan
    rel_az, rel_el = a_az - s_az, a_el - s_el
    em_az, em_el = (c_az - rel_az) * R2MD, (c_el - rel_el) * R2MD
    e_az, e_el = (c_az - th_az) * R2MD, (c_el - th_el) * R2MD
    # episode end (beyond_bounds's rule) and reward (step_cost)
    el = s_el + th_el
    term = (abs(e_az) > me or abs(e_el) > me or el < el_lo or el > el_hi
            or abs(az_off0 + th_az) > az_h)
    pe_el, pe_xel = (c_el - p_el) * R2MD, (c_az * xel_scale - p_xel) * R2MD
    s0, s1 = (pe_el, pe_xel) if pointing else (e_az, e_el)
    cost = step_cost(s0, s1, c0 - ap0, c1 - ap1, inv_es2, w)
    if term:
        cost += penalty
    if not cost < 1.0e300:  # NaN or inf
        raise FloatingPointError(f"the reward became {-cost} (servo errors {e_az}, {e_el} mdeg): the "
                                 "plant left the range it is meant for")
    # observation (layout OBS) and info
    o0, o1 = em_az * inv_es, em_el * inv_es
    o2, o3 = (em_az - em0_az) * rate_scale, (em_el - em0_el) * rate_scale
    if term or clamp_always:
        o0, o1 = _clamp(o0, OBS_ERROR_BOUND), _clamp(o1, OBS_ERROR_BOUND)
        o2, o3 = _clamp(o2, OBS_ERROR_RATE_BOUND), _clamp(o3, OBS_ERROR_RATE_BOUND)
    obs = _fromiter((o0, o1, o2, o3, c_deg_az, c_deg_el, cd_az, cd_el, rel_az * R2D, rel_el * R2D,
                     r0 * inv_rl, r1 * inv_rl), _F32, OBS_SIZE)
    info = {"servo_error_az_mdeg": e_az, "servo_error_el_mdeg": e_el,
            "measured_error_az_mdeg": em_az, "measured_error_el_mdeg": em_el,
            "pointing_error_el_mdeg": pe_el, "pointing_error_xel_mdeg": pe_xel,
            "wind_speed_mps": wind_speed, "wind_direction_rad": wind_direction,
            "action_unclipped": (a0, a1), "rate_command_az_deg_s": r0 * R2D,
            "rate_command_el_deg_s": r1 * R2D, "rate_limited": rate_hit, "accel_limited": acc_hit,
            "n_rate_limited": n_rate, "n_accel_limited": n_acc}
    return (obs, -cost, term, False, info), _tuple_new(ScalarState, (r0, r1, c0, c1, em_az, em_el, n_rate,
                                                                    n_acc, j + 1))
