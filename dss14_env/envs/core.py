"""What the step of the DSS14 environments is made of, besides its loops: the observation's
layout (named once: :data:`OBS`, :class:`ObsLayout`), the info keys, the configuration's
constants of a step (:class:`StepConstants`), the input checks and the step state.

FuncEnv-style: the step's dynamic state is one typed :class:`StepState` (previous rate command,
action and measured error, limiter hit counts, noise-block row);
:func:`dss14_env.envs.fused.reset_state` makes it with the first observation and info (both
environments reset through it), each step maps it to the next.  The step itself -- limiter,
encoders, errors, episode end, reward, observation and info values -- is written once, as
loops over N sub-environments, in :mod:`dss14_env.envs.fused`.

>>> OBS_SIZE, OBS_NAMES[:2]
(12, ('error_az', 'error_el'))
"""

from __future__ import annotations

import math
from copy import deepcopy
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from dss14_env.core.units import DEG, MDEG, R2MD
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
#: the info keys of every step, in order
INFO_KEYS = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg",
             "measured_error_el_mdeg", "pointing_error_el_mdeg", "pointing_error_xel_mdeg",
             "wind_speed_mps", "wind_direction_rad", "action_unclipped", "rate_command_az_deg_s",
             "rate_command_el_deg_s", "rate_limited", "accel_limited", "n_rate_limited",
             "n_accel_limited")

#: the value types a step's info shares between copies (immutable)
_ATOMS = frozenset((float, int, bool, str, type(None)))


class StepInfo(dict):
    """The single environment's step info: a plain ``dict`` that deep-copies in one pass.

    Its values are numbers, flags and tuples of numbers, which are immutable: ``copy.deepcopy``
    (what stable-baselines3's ``DummyVecEnv`` applies to every step's infos) shares them and
    deep-copies only a value of another type that a wrapper added (an array, a list).  Generic
    ``deepcopy`` walks every value through its dispatch and took most of the environment's
    time inside a ``DummyVecEnv`` step.

    >>> import copy
    >>> info = StepInfo(a=1.0, t=(0.5, -0.5), x=np.zeros(2))
    >>> c = copy.deepcopy(info)
    >>> type(c) is StepInfo and c["t"] == info["t"] and c["x"] is not info["x"]
    True
    """

    __slots__ = ()

    def __deepcopy__(self, memo: dict) -> StepInfo:
        out = StepInfo(self)
        memo[id(self)] = out
        for k, v in self.items():
            t = type(v)
            if t not in _ATOMS and not (t is tuple and all(type(e) in _ATOMS for e in v)):
                out[k] = deepcopy(v, memo)
        return out


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


# ------------------------------------------------------------------------------ state and reset
#: the reset-info keys of the first state, for both environments (both add the episode's:
#: :data:`dss14_env.envs.scenarios.EPISODE_INFO_KEYS`)
RESET_INFO_KEYS = ("servo_error_az_mdeg", "servo_error_el_mdeg", "measured_error_az_mdeg",
                   "measured_error_el_mdeg", "pointing_error_el_mdeg", "pointing_error_xel_mdeg",
                   "wind_speed_mps", "wind_direction_rad", "rate_command_az_deg_s", "rate_command_el_deg_s")


class StepState(NamedTuple):
    """The dynamic state a step reads and writes besides the plant (FuncEnv-style:
    :func:`dss14_env.envs.fused.reset_state` makes it, a step maps it to the next one).

    Each field holds every sub-environment (arrays ``(N, 2)``, ``j`` ``(N,)``; the single
    environment's is N = 1 with ``j`` an int).  The plant state lives beside it in each
    environment's own layout (the single one's step buffers, the vector one's slot-ordered
    batch).
    """

    #: previous applied rate command ``[az, el]``, rad/s (the limiter's memory)
    r_prev: Any
    #: previous clipped action ``[az, el]`` (the reward's action change)
    a_prev: Any
    #: previous measured servo error ``[az, el]``, mdeg (the observed error rate)
    em_prev: Any
    #: the episode's limiter hit counts ``[rate, accel]`` (floats: whole numbers)
    hits: Any
    #: the next step's row in its noise block
    j: Any
