"""The model-based controllers' own NOMINAL design model (LQG, MPC and the yardstick).

The simulator (``dss14_env``'s plant, possibly with randomised parameters) and the model a
controller is designed on are separate objects: everything here is built from the shipped
configuration (``configs/model.yaml``, ``configs/wind.yaml``, ``configs/controllers.yaml``)
through :func:`dss14_env.model.default_model` and :func:`dss14_env.wind.loads.default_wind_loads`,
never from an environment instance.

Design model (continuous time, SI, then discretised exactly for the control period)::

    theta' = C_v x_v + D_v [r; T_w]          encoder angles (rad): integrators of the encoder rate
    x_v'   = A_v x_v + B_v [r; T_w]          stable part of the rate loop, reduced to ``order``
    x_w'   = A_w x_w + G_w w                 wind shaping filter, w unit white noise
    T_w    = C_w x_w                         gust torques [Tw_az, Tw_el] (N*m)
    y      = theta + v,   E[v v^T] = (q^2 / 12) I,   q = 2 pi / 2^bits

Reduction.  The rate loop (60 states, :attr:`DSS14Model.rate_loop`) has two eigenvalues at 0:
the encoder angles, which are exact integrators of the encoder rates
(``C_enc A = C_enc_rate``, ``C_enc B = 0``).  :func:`split_rate_loop` separates them with an
ordered Schur form and a Sylvester equation (an exact similarity), leaving a stable 58-state
system ``[r; T_w] -> encoder rate``.  That system, with the inputs scaled by the rate limit and
by the gust-torque standard deviations at the design wind speed, is balanced (square-root
method, Lyapunov gramians from :func:`scipy.linalg.solve_continuous_lyapunov`) and reduced by
*balanced residualisation* (singular perturbation of the balanced realisation: the discarded
states are set to their quasi-steady values, so the DC gain -- the rate loop's 0.74 -- is kept
exactly; the additive error bound ``2 sum(sigma_i, i > order)`` of balanced truncation holds).
python-control's ``balred`` does the same but needs slycot, which the project does not depend
on.  ``order = None`` keeps all 58 states as they are (the full-order model of the yardstick;
no balancing, which for the weakest states is not resolved in double precision).

Wind.  ``wind=("design", speed)`` (LQG, MPC): a direction-free model, the front and the side
gust as two independent coherent components, ``T_w = g_front u_1 + g_side u_2`` with ``u_1``,
``u_2`` independent Davenport gusts (4th-order filter of :mod:`dss14_env.wind.gusts`) at the design
speed.  Any direction's gust gain ``g(theta) = g_front cos(theta) + g_side sin(theta)`` lies in
its span, front and side wind at full strength.  ``wind=(speed, direction)``
(the yardstick): the scenario's own fully coherent gust, ``T_w = g(direction) u``.

>>> dm = build_design_model(0.02, order=18)
>>> dm.n, dm.n_theta, dm.n_v, dm.n_w
(28, 2, 18, 8)
>>> bool(np.allclose(dm.rate_dc_gain(), full_rate_dc_gain(), rtol=1e-8))
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from scipy import linalg

from dss14_env.core.schema import ConfigError, Param, load_section, read_config, spec
from dss14_env.core.threads import single_threaded
from dss14_env.core.units import MDEG, WIND_DIRECTIONS
from dss14_env.model.assembly import DSS14Model, default_model
from dss14_env.model.linsys import balance, discretize, noise_factor
from dss14_env.wind.loads import WindLoads, default_wind_loads, direction_angle

ENCODER_OUTPUTS = ("enc_az", "enc_el")
RATE_OUTPUTS = ("enc_rate_az", "enc_rate_el")
#: the structure's pointing outputs of the rate loop (rad): elevation, cross-elevation
POINTING_OUTPUTS = ("point_el", "point_xel")
#: what a design's quadratic error term scores: the servo error at its encoders or the dish's
#: true pointing error
ERROR_OUTPUTS = ("encoder", "pointing")
#: what the encoders measure (the environment's ``encoders``): the drive angles or the
#: structure's pointing angles at the axes (az ``point_xel / cos E``, el ``point_el``)
ENCODER_KINDS = ("drive", "axis")
COMMAND_INPUTS = ("r_a", "r_e")
WIND_INPUTS = ("Tw_az", "Tw_el")
#: floor of the measurement-noise standard deviation (rad): 1e-3 mdeg, for exact encoders
MIN_MEASUREMENT_NOISE = 1e-3 * MDEG


# ------------------------------------------------------------------------- configuration
@dataclass(frozen=True)
class DesignConfig:
    """Section ``design`` of ``configs/controllers.yaml`` (SI)."""

    order: int = spec("1", kind="integer", lo=2)
    wind_speed: float = spec("m/s", lo=0.0, lo_open=True)
    encoder_bits: int = spec("1", kind="integer", lo=1)
    rate_limit: float = spec("rad/s", lo=0.0, lo_open=True)
    accel_limit: float = spec("rad/s^2", lo=0.0, lo_open=True)


@dataclass(frozen=True)
class LQGConfig:
    """Section ``lqg``: LQR weights (per control period), estimator and command shaper.

    ``wind_model`` (a string, not a number): ``"inferred"`` (the wind direction and speed read
    from the start command, :func:`infer_wind`) or ``"direction-free"``.
    ``axis_action_change_weight`` replaces ``action_change_weight`` when the encoders sit at the
    axes (the environment's ``encoders="axis"``).
    """

    wind_model: str = spec(None, kind="str", choices=("inferred", "direction-free"))
    error_weight: float = spec("1", lo=0.0, lo_open=True)
    action_change_weight: float = spec("1", lo=0.0, lo_open=True)
    axis_action_change_weight: float = spec("1", lo=0.0, lo_open=True)
    integral_weight: float = spec("1", lo=0.0, lo_open=True)
    integral_clip: float = spec("rad", lo=0.0, lo_open=True)
    input_noise: float = spec("1", lo=0.0)
    disturbance_drift: float = spec("1", lo=0.0)
    measurement_noise: float = spec("rad", lo=0.0)
    min_wind_speed: float = spec("m/s", lo=0.0, lo_open=True)
    shaper: int = spec("1", kind="integer", lo=0, hi=1)
    shaper_rate: float = spec("rad/s", lo=0.0, lo_open=True)
    shaper_accel: float = spec("rad/s^2", lo=0.0, lo_open=True)
    shaper_accel_max: float = spec("rad/s^2", lo=0.0, lo_open=True)
    reference_pull: float = spec("1/s", lo=0.0, lo_open=True)
    reference_accel_share: float = spec("1", lo=0.0, hi=1.0, lo_open=True)


@dataclass(frozen=True)
class MPCConfig:
    """Section ``mpc``: horizon, soft error constraint and OSQP settings."""

    horizon: int = spec("1", kind="integer", lo=2)
    shaper: int = spec("1", kind="integer", lo=0, hi=1)
    action_change_weight: float = spec("1", lo=0.0, lo_open=True)
    error_soft_limit: float = spec("rad", lo=0.0, lo_open=True)
    slack_weight_linear: float = spec("1", lo=0.0, lo_open=True)
    slack_weight_quadratic: float = spec("1", lo=0.0, lo_open=True)
    eps_abs: float = spec("1", lo=0.0, lo_open=True)
    eps_rel: float = spec("1", lo=0.0, lo_open=True)
    max_iter: int = spec("1", kind="integer", lo=1)


@dataclass(frozen=True)
class PointingConfig:
    """Section ``pointing``: the pointing-aware LQG and MPC (everything else as ``lqg``/``mpc``).

    Their quadratic error term is the dish's true pointing error ``[el, xel]`` (the structure's
    pointing outputs of the design model) plus ``encoder_error_weight`` times the encoder
    servo error; ``order`` is the reduced order of a design model that balances the
    deformation outputs too.
    """

    order: int = spec("1", kind="integer", lo=2)
    action_change_weight: float = spec("1", lo=0.0, lo_open=True)
    encoder_error_weight: float = spec("1", lo=0.0)
    mpc_action_change_weight: float = spec("1", lo=0.0, lo_open=True)


@dataclass(frozen=True)
class MonopulseConfig:
    """Section ``monopulse``: the controllers that use the monopulse sensor
    (:mod:`dss14_env.baselines.monopulse`).

    ``outer_gain``: the DSN arrangement's outer loop (``pi_monopulse``), an integrator on the
    measured pointing error around the report's PI; ``action_change_weight`` and
    ``encoder_error_weight``: the fused LQG's (``lqg_monopulse``) in place of the ``pointing``
    section's, everything else as ``pointing`` and ``lqg``.
    """

    outer_gain: float = spec("1/s", lo=0.0, lo_open=True)
    action_change_weight: float = spec("1", lo=0.0, lo_open=True)
    encoder_error_weight: float = spec("1", lo=0.0)


@dataclass(frozen=True)
class ScheduleConfig:
    """Section ``schedule``: the wind-scheduled pointing LQG (``lqg_pointing_sched``,
    :mod:`dss14_env.baselines.scheduled`).

    ``wind_speeds``: the grid (ascending) that a measured mean wind speed is rounded to, the
    nearest entry, whose design carries the gust model at that speed;
    ``measurement_noise``: that design's extra white measurement noise in the Kalman filter
    (``lqg.measurement_noise`` of the grid point; one per entry; everything else as
    ``lqg_pointing``).
    """

    wind_speeds: tuple = spec("m/s", kind="list", lo=0.0, lo_open=True)
    measurement_noise: tuple = spec("rad", kind="list", lo=0.0)

    def problem(self) -> str | None:
        """What is wrong with the section (lists of other lengths, a grid not ascending), or None."""
        if len(self.measurement_noise) != len(self.wind_speeds):
            return (f"field 'schedule.measurement_noise': needs one entry per wind speed "
                    f"({len(self.wind_speeds)}), got {len(self.measurement_noise)}")
        if any(np.diff(self.wind_speeds) <= 0):
            return "field 'schedule.wind_speeds': must be strictly ascending"
        return None


@dataclass(frozen=True)
class ControllersConfig:
    """The whole ``configs/controllers.yaml`` in SI plus its parameter registry."""

    design: DesignConfig
    lqg: LQGConfig
    mpc: MPCConfig
    pointing: PointingConfig
    params: dict
    path: str
    monopulse: MonopulseConfig | None = None
    schedule: ScheduleConfig | None = None


def load_controllers_config(path: str | Path | None = None) -> ControllersConfig:
    """Load and validate ``configs/controllers.yaml`` (or ``path``, or a shipped name).

    :param path: YAML file or shipped configuration name, default ``"controllers"``
    :return: the configuration in SI units
    :raises ConfigError: naming the field and the file of the first problem found
    """
    data, source = read_config("controllers" if path is None else path, kind="controllers")
    registry: dict[str, Param] = {}
    kw = dict(documented=True, registry=registry, defaults=False)
    sections = {"design": DesignConfig, "lqg": LQGConfig, "mpc": MPCConfig, "pointing": PointingConfig,
                "monopulse": MonopulseConfig, "schedule": ScheduleConfig}
    extra = set(data) - set(sections)
    if extra:
        raise ConfigError(f"{source}: unknown section(s) {sorted(extra)}; known: {sorted(sections)}")
    optional = {"monopulse", "schedule"}  # a file without them has no such controllers' settings
    blocks = {name: load_section(cls, data.get(name), source, name, **kw)
              for name, cls in sections.items() if name not in optional or name in data}
    problem = blocks["schedule"].problem() if "schedule" in blocks else None
    if problem is not None:
        raise ConfigError(f"{source}: {problem}")
    return ControllersConfig(blocks["design"], blocks["lqg"], blocks["mpc"], blocks["pointing"], registry,
                             source, blocks.get("monopulse"), blocks.get("schedule"))


@lru_cache(maxsize=1)
def default_controllers_config() -> ControllersConfig:
    """The shipped controller configuration (cached)."""
    return load_controllers_config()


def encoder_step(bits: int) -> float:
    """Encoder quantisation step ``2 pi / 2^bits`` in rad (20 bits: 0.343 mdeg).

    >>> round(encoder_step(20) / MDEG, 4)
    0.3433
    """
    if int(bits) != bits or bits < 1:
        raise ValueError(f"encoder bits must be a positive integer, got {bits!r}")
    return 2.0 * math.pi / 2.0 ** int(bits)


# ------------------------------------------------------------------------- reduction
@dataclass(frozen=True)
class StableRateLoop:
    """The rate loop split into encoder-angle integrators and a stable part (exact).

    ``theta' = C x + D [r; T_w]``, ``x' = A x + B [r; T_w]`` with ``A`` Hurwitz; inputs in the
    order ``r_a, r_e, Tw_az, Tw_el``.  The structure's deformation ``delta = Cd x`` (rad, rows
    el, xel) is the pointing less its rigid part: ``[point_el, point_xel] = S theta + delta``
    with ``S = [[0, 1], [cos E, 0]]`` (:func:`rigid_pointing`).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    Cd: np.ndarray
    xel_scale: float


def split_rate_loop(model: DSS14Model) -> StableRateLoop:
    """Separate the encoder integrators from the stable part of the rate loop.

    The (balanced, :func:`dss14_env.model.linsys.balance`) rate loop is brought to an ordered real
    Schur form with the stable eigenvalues first; a Sylvester equation removes the coupling
    block, so ``x = T [x_s; x_0]`` with ``x_s' = A_s x_s + B_s u``.  The encoder rate reads
    only ``x_s`` (the zero modes are the rigid rotations), and the angle is its integral.  A
    rigid rotation turns the beam with the encoders, so the deformation (pointing less
    ``S theta``) reads only ``x_s`` too (checked).

    :param model: calibrated servo model
    :raises ValueError: if the rate loop does not have exactly two eigenvalues at zero, the
        encoder angle is not the integral of the encoder rate, or a rigid rotation deforms
    """
    rl = model.rate_loop
    il, ol = list(rl.input_labels), list(rl.output_labels)
    ii = [il.index(s) for s in COMMAND_INPUTS + WIND_INPUTS]
    ie = [ol.index(s) for s in ENCODER_OUTPUTS]
    iv = [ol.index(s) for s in RATE_OUTPUTS]
    A, B, C, _ = balance(rl.A, rl.B[:, ii], rl.C)
    scale = np.abs(C[iv]).max()
    if (np.abs(C[ie] @ A - C[iv]).max() > 1e-9 * scale or np.abs(C[ie] @ B).max() > 1e-9 * scale
            or np.any(rl.D[np.ix_(ie + iv, ii)])):
        raise ValueError("the rate loop's encoder angle is not the integral of its encoder rate")
    tol = 1e-8 * max(1.0, np.abs(A).max())
    T, Z, n_s = linalg.schur(A, output="real", sort=lambda re, im: re < -tol)
    if A.shape[0] - n_s != 2:
        raise ValueError(f"expected 2 rigid-body (zero) eigenvalues in the rate loop, found "
                         f"{A.shape[0] - n_s}")
    X = linalg.solve_sylvester(T[:n_s, :n_s], -T[n_s:, n_s:], -T[:n_s, n_s:])
    M = np.eye(A.shape[0])
    M[:n_s, n_s:] = X
    Tm = Z @ M
    Ti = np.linalg.solve(Tm, np.eye(A.shape[0]))
    As = (Ti @ A @ Tm)[:n_s, :n_s]
    Bs = (Ti @ B)[:n_s]
    Cs = (C[iv] @ Tm)[:, :n_s]
    xel_scale = math.cos(model.cfg.structure.elevation_angle)
    ip = [ol.index(s) for s in POINTING_OUTPUTS]
    if np.any(rl.D[np.ix_(ip, ii)]):
        raise ValueError("the rate loop's pointing outputs have a feedthrough")
    Cdef = (C[ip] - rigid_pointing(xel_scale) @ C[ie]) @ Tm
    if np.abs(Cdef[:, n_s:]).max() > 1e-9 * np.abs(C[ip]).max():
        raise ValueError("a rigid rotation of the rate loop deforms the structure")
    return StableRateLoop(As, Bs, Cs, np.zeros((2, len(ii))), Cdef[:, :n_s], xel_scale)


def rigid_pointing(xel_scale: float) -> np.ndarray:
    """``S``: the pointing ``[el, xel]`` of a rigid rotation by the encoder angles ``[az, el]``
    (the structure's xel output of an azimuth rotation is ``cos(E)`` times it).
    """
    return np.array([[0.0, 1.0], [float(xel_scale), 0.0]])


def balanced_reduction(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray,
                       order: int | None, method: str = "residualise"
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Square-root balanced reduction of a stable system (scipy only).

    :param A: (n, n) Hurwitz state matrix
    :param B: (n, m) input matrix (inputs already scaled to comparable size)
    :param C: (p, n) output matrix (outputs already scaled)
    :param D: (p, m) feedthrough
    :param order: states kept; ``None`` keeps every state: with ``"residualise"`` the system
        itself (exact), with ``"truncate"`` the balanced realisation of its minimal part.  (A
        balanced realisation of every state divides by the square roots of Hankel singular
        values down to 1e-13 of the largest, below what Gramians solved in double precision
        resolve: with OpenBLAS's Haswell kernel it came out unstable.)  A reduced order keeps
        the balanced coordinates of its states only; the residualised ones are taken in an
        orthonormal basis of their subspace, which gives the same reduced system
    :param method: ``"residualise"`` (singular perturbation, DC gain exact) or ``"truncate"``
    :return: ``(A_r, B_r, C_r, D_r, hsv)`` with the Hankel singular values of the full system
    :raises ValueError: if ``A`` is not Hurwitz, the order is out of range or the method unknown
    """
    n = A.shape[0]
    if np.max(np.linalg.eigvals(A).real) >= 0:
        raise ValueError("balanced reduction needs an asymptotically stable system")
    if method not in ("residualise", "truncate"):
        raise ValueError(f"unknown reduction method {method!r}; use 'residualise' or 'truncate'")
    Wc = linalg.solve_continuous_lyapunov(A, -B @ B.T)
    Wo = linalg.solve_continuous_lyapunov(A.T, -C.T @ C)
    Lc, Lo = noise_factor(Wc), noise_factor(Wo)
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    k = n if order is None else int(order)
    if not 1 <= k <= n:
        raise ValueError(f"reduced order must be in [1, {n}], got {order}")
    if order is None and method == "residualise":
        return A.copy(), B.copy(), C.copy(), D.copy(), s
    k = min(k, int(np.sum(s > s[0] * 1e-13)))  # at most the minimal part
    sq = np.sqrt(s[:k])
    T1 = Lc @ Vt[:k].T / sq
    Ti1 = (U[:, :k] / sq).T @ Lo.T
    A11, B1, C1 = Ti1 @ A @ T1, Ti1 @ B, C @ T1
    if method == "truncate" or k == n:
        return A11, B1, C1, D.copy(), s
    # the residualised states: any basis of the complement (the result does not depend on it),
    # T2 spanning the null space of Ti1 and Ti2 that of T1' (never the balanced coordinates of
    # the weak states, which divide by the square roots of their tiny singular values)
    T2 = linalg.null_space(Ti1)
    W = linalg.null_space(T1.T)
    Ti2 = np.linalg.solve(W.T @ T2, W.T)
    A12, A21, A22 = Ti1 @ A @ T2, Ti2 @ A @ T1, Ti2 @ A @ T2
    X = np.linalg.solve(A22, np.hstack([A21, Ti2 @ B]))
    X21, X2b = X[:, :k], X[:, k:]
    C2 = C @ T2
    return A11 - A12 @ X21, B1 - A12 @ X2b, C1 - C2 @ X21, D - C2 @ X2b, s


def gust_torque_std(loads: WindLoads, speed: float, direction: str | float) -> np.ndarray:
    """Standard deviation of the gust torques ``[Tw_az, Tw_el]`` (N*m) for one direction."""
    A_w, G_w, C_w, _ = loads.disturbance(speed, direction)
    P = linalg.solve_continuous_lyapunov(A_w, -G_w @ G_w.T)
    return np.sqrt(np.diag(C_w @ P @ C_w.T))


@dataclass(frozen=True)
class ReducedRateLoop:
    """The rate loop as ``theta' = C x + D u``, ``x' = A x + B u``, ``u = [r; T_w]`` (SI).

    With the pointing outputs (``pointing=True`` of :func:`reduce_rate_loop`) the deformation
    ``delta = Cd x + Dd u`` (rad, el and xel) is kept too; ``Cd`` and ``Dd`` are None otherwise.

    :param hsv: Hankel singular values of the scaled stable part (all 58)
    :param input_scale: scaling used for the balancing (rad/s for r, N*m for T_w)
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    hsv: np.ndarray
    input_scale: np.ndarray
    order: int
    Cd: np.ndarray | None = None
    Dd: np.ndarray | None = None
    xel_scale: float = 1.0

    def freqresp_angle(self, f_hz: Sequence[float]) -> np.ndarray:
        """Frequency response ``[r; T_w] -> theta`` (``(len(f), 2, 4)``), f > 0."""
        out = []
        eye = np.eye(self.A.shape[0])
        for f in np.atleast_1d(np.asarray(f_hz, float)):
            s = 2j * math.pi * f
            out.append((self.C @ np.linalg.solve(s * eye - self.A, self.B) + self.D) / s)
        return np.array(out)


_CACHE: dict[tuple, Any] = {}


def _cached(key: tuple, refs: tuple, build: Any) -> Any:
    """Memoise on object identity (the model and the loads are not hashable); the referenced
    objects are kept alive with the entry so their ids stay unique.
    """
    k = key + tuple(id(r) for r in refs)
    if k not in _CACHE:
        if len(_CACHE) > 64:
            _CACHE.clear()
        _CACHE[k] = (build(), refs)
    return _CACHE[k][0]


def reduce_rate_loop(order: int | None, model: DSS14Model | None = None,
                     loads: WindLoads | None = None, speed: float | None = None,
                     rate_limit: float | None = None, pointing: bool = False) -> ReducedRateLoop:
    """Balanced residualisation of the rate loop's stable part (see the module docstring).

    :param order: states kept of the 58-state stable part; ``None``: all (exact)
    :param model: nominal model, default :func:`default_model`
    :param loads: wind loads, default :func:`default_wind_loads`
    :param speed: design wind speed (m/s) for the torque scaling, default from the config
    :param rate_limit: rate-command scaling (rad/s), default from the config
    :param pointing: balance and keep the structure's deformation as outputs too (scaled by
        :data:`DEFORMATION_SCALE_S` times the rate limit), for the pointing designs
    """
    model = model or default_model()
    loads = loads or default_wind_loads()
    return _cached(("reduce", order, speed, rate_limit, bool(pointing)), (model, loads),
                   lambda: _reduce(order, model, loads, speed, rate_limit, bool(pointing)))


#: output scaling of the deformation in the balancing of a pointing design, s: a deformation of
#: this many seconds of full-rate motion weighs like a full-rate encoder-rate error
DEFORMATION_SCALE_S = 0.01


def _reduce(order, model, loads, speed, rate_limit, pointing=False) -> ReducedRateLoop:
    cfg = default_controllers_config().design
    speed = cfg.wind_speed if speed is None else float(speed)
    rate_limit = cfg.rate_limit if rate_limit is None else float(rate_limit)
    srl = _split(model)
    t_std = np.max([gust_torque_std(loads, speed, d) for d in WIND_DIRECTIONS], axis=0)
    su = np.concatenate([[rate_limit, rate_limit], t_std])
    sy = np.full(2, rate_limit)
    C, D = srl.C, srl.D
    if pointing:
        sy = np.concatenate([sy, np.full(2, DEFORMATION_SCALE_S * rate_limit)])
        C, D = np.vstack([C, srl.Cd]), np.vstack([D, np.zeros_like(D)])
    Ar, Br, Cr, Dr, hsv = balanced_reduction(srl.A, srl.B * su, C / sy[:, None], D * su / sy[:, None],
                                             order)
    Cr, Dr = Cr * sy[:, None], Dr * sy[:, None] / su
    Cd, Dd = (Cr[2:], Dr[2:]) if pointing else (None, None)
    return ReducedRateLoop(Ar, Br / su, Cr[:2], Dr[:2], hsv, su, Ar.shape[0], Cd, Dd, srl.xel_scale)


def _split(model: DSS14Model) -> StableRateLoop:
    return _cached(("split",), (model,), lambda: split_rate_loop(model))


def full_rate_dc_gain(model: DSS14Model | None = None) -> np.ndarray:
    """DC gain (2x2) rate command -> encoder rate of the full rate loop."""
    srl = _split(model or default_model())
    return (srl.D - srl.C @ np.linalg.solve(srl.A, srl.B))[:, :2]


def reduction_error(orders: Sequence[int], f_hz: Sequence[float] | None = None,
                    band_hz: float = 3.0) -> list[dict]:
    """Frequency-response error of reduced rate loops against the full one.

    For each order and each diagonal channel (``r_a -> enc_az``, ``r_e -> enc_el``,
    ``Tw_az -> enc_az``, ``Tw_el -> enc_el``): the largest relative error
    ``|G_r - G| / |G|`` over ``f <= band_hz`` and the largest error over all frequencies
    relative to the channel's peak ``max |G|``.

    :param orders: reduced orders to compare
    :param f_hz: frequency grid (Hz), default 400 log-spaced points 1 mHz - 25 Hz (Nyquist at 50 Hz)
    :param band_hz: upper end of the band of the relative error, default 3 Hz
    :return: list of dicts (JSON-ready), one per order
    """
    f = np.geomspace(1e-3, 25.0, 400) if f_hz is None else np.asarray(f_hz, float)
    full = reduce_rate_loop(None)
    G = full.freqresp_angle(f)
    chans = {"r_a->enc_az": (0, 0), "r_e->enc_el": (1, 1), "Tw_az->enc_az": (0, 2), "Tw_el->enc_el": (1, 3)}
    out = []
    for k in orders:
        red = reduce_rate_loop(int(k))
        E = red.freqresp_angle(f) - G
        row: dict[str, Any] = {"order": int(k),
                               "hinf_bound_rel": float(2 * red.hsv[int(k):].sum() / red.hsv[0])}
        for name, (o, i) in chans.items():
            g = np.abs(G[:, o, i])
            row[name] = {"rel_in_band": float(np.max(np.abs(E[f <= band_hz, o, i]) / g[f <= band_hz])),
                         "rel_to_peak": float(np.max(np.abs(E[:, o, i])) / g.max())}
        out.append(row)
    return out


# ------------------------------------------------------------------------- design model
@dataclass(frozen=True)
class DesignModel:
    """Discrete design model of one control period (see the module docstring).

    State ``x = [theta (2), x_v (n_v), x_w (n_w)]``; input ``r`` (applied rate commands, rad/s);
    measurement ``y = C x + v`` (encoder angles, rad).  ``Ad, Bd`` are the exact ZOH
    discretisation, ``Qd`` the covariance of the wind noise increment (Van Loan), ``R`` the
    quantisation-noise covariance.  The continuous matrices ``A, B, G`` are kept too.
    """

    dt: float
    A: np.ndarray
    B: np.ndarray
    G: np.ndarray
    C: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    Qd: np.ndarray
    R: np.ndarray
    n_theta: int
    n_v: int
    n_w: int
    order: int
    wind: Any
    hsv: np.ndarray = field(repr=False)
    Cp: np.ndarray | None = field(default=None, repr=False)
    xel_scale: float = 1.0
    error_output: str = "encoder"
    encoders: str = "drive"

    @property
    def n(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    def disturbance_measurement(self) -> np.ndarray:
        """``(2, 2)``: what a command-level disturbance ``d`` (the estimator's mean-torque state,
        rad/s) adds to the measurement at rest: zero for drive encoders; for axis encoders the
        static deflection they see, ``S^-1 F`` (:func:`static_deflection_map`).
        """
        if self.encoders == "drive":
            return np.zeros((2, 2))
        return np.linalg.solve(rigid_pointing(self.xel_scale), static_deflection_map())

    def estimator_output(self, n_d: int) -> np.ndarray:
        """The measurement matrix ``(2, n + n_d)`` of the estimator state ``[x; d]``."""
        return np.hstack([self.C, self.disturbance_measurement()[:, :n_d]])

    @property
    def Cz(self) -> np.ndarray:
        """The outputs whose error the design scores: the encoder angles ``C`` (rows az, el) or
        the dish's pointing ``Cp`` (rows el, xel), by :attr:`error_output`.
        """
        return self.Cp if self.error_output == "pointing" else self.C

    def deformation_map(self) -> np.ndarray:
        """``Cd`` ``(2, n)``: the deformation part of the pointing, ``Cp x - S theta`` (rad).

        :raises ValueError: for a model built without the pointing outputs
        """
        if self.Cp is None:
            raise ValueError("this design model has no pointing outputs (build it with pointing=True)")
        out = self.Cp.copy()
        out[:, :2] -= rigid_pointing(self.xel_scale)
        return out

    def rate_dc_gain(self) -> np.ndarray:
        """DC gain (2x2) rate command -> encoder rate of the model."""
        nv = slice(2, 2 + self.n_v)
        Av, Bv, Cv = self.A[nv, nv], self.B[nv], self.A[:2, nv]
        return self.B[:2] - Cv @ np.linalg.solve(Av, Bv)

    def reference_state(self, c: np.ndarray, c_rate: np.ndarray, c_acc: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
        """State and command of the model following ``c + c_rate t + c_acc t^2 / 2`` (no wind).

        For a ramp (``c_acc = 0``): ``A x + B r = [c_rate; 0]``, ``theta = c`` -- the rate-loop
        states at their equilibrium for the constant command ``r`` that moves the encoders at
        ``c_rate``.  With an acceleration the rate-loop states and the command grow linearly,
        ``x_v = x_0 + x_1 t``, ``r = r_0 + r_1 t``; matching ``theta''= c_acc`` gives
        ``[A_v B_v; C_v D_v] [x_1; r_1] = [0; c_acc]`` and ``[A_v B_v; C_v D_v] [x_0; r_0] =
        [x_1; c_rate]``.  The state and command at t = 0 are returned.

        :param c: command angles (rad), shape (2,)
        :param c_rate: command rates (rad/s), shape (2,)
        :param c_acc: command accelerations (rad/s^2), default zero
        :return: ``(x_ref, r_ref)``
        """
        nv = slice(2, 2 + self.n_v)
        M = np.block([[self.A[nv, nv], self.B[nv]], [self.A[:2, nv], self.B[:2]]])
        k = self.n_v
        rhs1 = np.zeros(k + 2)
        if c_acc is not None:
            rhs1[k:] = c_acc
        s1 = np.linalg.solve(M, rhs1)
        rhs0 = np.concatenate([s1[:k], np.asarray(c_rate, float)])
        s0 = np.linalg.solve(M, rhs0)
        x = np.zeros(self.n)
        x[:2] = c
        x[nv] = s0[:k]
        return x, s0[k:]


def _wind_model(loads: WindLoads, wind: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A_w, G_w, C_w)`` of the gust torques, see :func:`build_design_model`."""
    if isinstance(wind, tuple) and len(wind) == 2 and wind[0] == "design":
        # direction-free: the front and the side gust as two independent coherent components
        speed = float(wind[1])
        f = loads.gust_filter(speed)
        a, g, c = (np.asarray(m, float) for m in (f.A, f.B, f.C))
        A_w = linalg.block_diag(a, a)
        G_w = linalg.block_diag(g, g)
        C_w = np.hstack([np.outer(loads.gust_gain(speed, d), c) for d in WIND_DIRECTIONS])
        return A_w, G_w, C_w
    if isinstance(wind, tuple) and len(wind) == 2:
        speed, direction = float(wind[0]), wind[1]
        direction_angle(direction)  # validates
        A_w, G_w, C_w, _ = loads.disturbance(speed, direction)
        return A_w, G_w, C_w
    raise ValueError(f"wind must be ('design', speed) or (speed, direction), got {wind!r}")


def build_design_model(dt: float, order: int | None | str = "config", wind: Any = None,
                       encoder_noise: float = 0.0, bits: int | None | str = "config",
                       model: DSS14Model | None = None, loads: WindLoads | None = None,
                       pointing: bool = False, error_output: str = "encoder",
                       encoders: str = "drive") -> DesignModel:
    """Nominal design model, discretised exactly for the period ``dt``.

    :param dt: control period, s
    :param order: reduced order of the rate loop's stable part; ``"config"`` (default) takes
        ``design.order`` of ``configs/controllers.yaml``; ``None`` keeps the full 58 states
    :param wind: ``None`` (default): the direction-free design wind at the configured speed,
        ``("design", speed)``; or ``(speed, direction)``: the coherent gust of one scenario
    :param encoder_noise: extra white measurement noise (rad rms) on top of the quantisation
    :param bits: encoder resolution (bits per turn) for the quantisation noise ``q^2/12``;
        ``"config"``: ``design.encoder_bits``; ``None``: exact encoder (a floor of
        :data:`MIN_MEASUREMENT_NOISE` keeps the Kalman problem regular)
    :param model: nominal model, default :func:`default_model`
    :param loads: wind loads, default :func:`default_wind_loads`
    :param pointing: carry the structure's pointing outputs ``Cp`` (rows el, xel; rad), the
        reduction balancing them too (:func:`reduce_rate_loop`)
    :param error_output: ``"encoder"`` or ``"pointing"`` (implies ``pointing``): the outputs
        whose error a design on this model scores (:attr:`DesignModel.Cz`)
    :param encoders: ``"drive"`` (the measurement ``C`` reads the drive angles) or ``"axis"``
        (implies ``pointing``: ``C = S^-1 Cp``, the structure's angles at the axes, as the
        environment's ``encoders="axis"`` reads them)
    :raises ValueError: for a non-positive ``dt``, an unknown wind specification, error output
        or encoder kind
    """
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive period in s, got {dt!r}")
    if error_output not in ERROR_OUTPUTS:
        raise ValueError(f"error_output must be one of {ERROR_OUTPUTS}, got {error_output!r}")
    if encoders not in ENCODER_KINDS:
        raise ValueError(f"encoders must be one of {ENCODER_KINDS}, got {encoders!r}")
    pointing = bool(pointing) or error_output == "pointing" or encoders == "axis"
    cfg = default_controllers_config().design
    if order == "config":
        order = cfg.order
    if wind is None:
        wind = ("design", cfg.wind_speed)
    if bits == "config":
        bits = cfg.encoder_bits
    model = model or default_model()
    loads = loads or default_wind_loads()
    wind = tuple(wind)
    key = ("design", float(dt), order, wind, float(encoder_noise), bits, pointing, error_output, encoders)
    return _cached(key, (model, loads),
                   lambda: _build(float(dt), order, wind, float(encoder_noise), bits, model, loads,
                                  pointing, error_output, encoders))


@single_threaded
def _build(dt, order, wind, encoder_noise, bits, model, loads, pointing=False,
           error_output="encoder", encoders="drive") -> DesignModel:
    red = reduce_rate_loop(order, model, loads, pointing=pointing)
    A_w, G_w, C_w = _wind_model(loads, wind)
    nv, nw = red.A.shape[0], A_w.shape[0]
    n = 2 + nv + nw
    A = np.zeros((n, n))
    B = np.zeros((n, 2))
    G = np.zeros((n, G_w.shape[1]))
    v, w = slice(2, 2 + nv), slice(2 + nv, n)
    A[:2, v] = red.C
    A[:2, w] = red.D[:, 2:] @ C_w
    A[v, v] = red.A
    A[v, w] = red.B[:, 2:] @ C_w
    A[w, w] = A_w
    B[:2] = red.D[:, :2]
    B[v] = red.B[:, :2]
    G[w] = G_w
    C = np.zeros((2, n))
    C[:, :2] = np.eye(2)
    Ad, Bd, Qd = discretize(A, B, dt, G)
    q2 = encoder_step(bits) ** 2 / 12.0 if bits is not None else 0.0
    R = max(q2 + encoder_noise ** 2, MIN_MEASUREMENT_NOISE ** 2) * np.eye(2)
    Cp = None
    if pointing:
        Cp = np.zeros((2, n))
        Cp[:, :2] = rigid_pointing(red.xel_scale)
        Cp[:, v] = red.Cd
        Cp[:, w] = red.Dd[:, 2:] @ C_w
        if encoders == "axis":
            C = np.linalg.solve(rigid_pointing(red.xel_scale), Cp)
    return DesignModel(dt, A, B, G, C, Ad, Bd, Qd, R, 2, nv, nw, nv, wind, red.hsv, Cp,
                       red.xel_scale, error_output, encoders)


def smallest_order(budget_rel: float) -> int:
    """Smallest even order whose balanced-reduction error bound ``2 sum sigma_tail / sigma_1``
    is at most ``budget_rel`` (the rule behind ``design.order``).
    """
    hsv = reduce_rate_loop(None).hsv
    for k in range(2, hsv.size + 1, 2):
        if 2 * hsv[k:].sum() / hsv[0] <= budget_rel:
            return k
    return hsv.size


# ------------------------------------------------------------------------- wind inference
def rate_dc_gains(model: DSS14Model | None = None) -> np.ndarray:
    """DC gains (2x4) ``[r_a, r_e, Tw_az, Tw_el] -> encoder rates`` of the nominal rate loop."""
    srl = _split(model or default_model())
    return srl.D - srl.C @ np.linalg.solve(srl.A, srl.B)


def deformation_dc_gains(model: DSS14Model | None = None) -> np.ndarray:
    """DC gains (2x4) ``[r_a, r_e, Tw_az, Tw_el] -> deformation [el, xel]`` (rad per input) of the
    nominal rate loop's stable part (:class:`StableRateLoop`).
    """
    srl = _split(model or default_model())
    return -srl.Cd @ np.linalg.solve(srl.A, srl.B)


def static_deflection_map(model: DSS14Model | None = None) -> np.ndarray:
    """``F`` (2x2): the structure's static deflection ``[el, xel]`` (rad) under the constant
    wind torque that a command-level input disturbance ``d`` (rad/s, the LQG estimator's) stands
    for, with the encoders held still.

    The estimator models the mean wind torque ``T`` as a command offset ``d`` with the same
    effect on the encoder rate, ``G_r d = G_T T`` (:func:`rate_dc_gains`); held still
    (``G_r r + G_T T = 0``, so ``r = -d``) the structure deflects by ``Def_r r + Def_T T``
    (:func:`deformation_dc_gains`), hence ``F = Def_T G_T^-1 G_r - Def_r``.  The model itself,
    driven by ``r + d = 0``, does not deflect: the pointing designs add ``F d`` to it.
    """
    G, Dg = rate_dc_gains(model), deformation_dc_gains(model)
    return Dg[:, 2:] @ np.linalg.solve(G[:, 2:], G[:, :2]) - Dg[:, :2]


def infer_wind(r0: np.ndarray, c_rate0: np.ndarray, model: DSS14Model | None = None,
               loads: WindLoads | None = None) -> tuple[float, float]:
    """Wind speed and direction read from the command that holds the antenna at the start.

    The environment starts in steady motion at the command rate ``c_rate0`` under the wind
    torque of t = 0, held by the applied command ``r0`` (both observed).  With the nominal DC
    gains ``v = G_r r + G_T T`` the torque is ``T = G_T^-1 (c_rate0 - G_r r0)``.  The quasi-steady
    load model gives ``T = (rho A D / 2) U^2 (1 + 2 u_0 / U) (C_front cos theta + C_side sin
    theta)``, so ``[U^2 cos theta, U^2 sin theta]`` solves a 2x2 system: the direction is exact
    on the nominal plant, the speed is off by the start gust ``u_0`` (about +-17 % at 1 sigma).
    A gust gain is proportional to the same vector, which is what makes the direction worth
    knowing.  The direction is returned modulo pi (``T`` and ``-T`` give the same gust model).

    :param r0: applied rate command at the start, rad/s
    :param c_rate0: command rate at the start, rad/s
    :return: ``(U, theta)`` in m/s and rad (theta in [0, pi))
    """
    loads = loads or default_wind_loads()
    G = rate_dc_gains(model)
    T = np.linalg.solve(G[:, 2:], np.asarray(c_rate0, float) - G[:, :2] @ np.asarray(r0, float))
    q = 0.5 * loads.cfg.air_density * loads.dish_area * loads.cfg.dish_diameter
    M = q * np.column_stack([loads.c_front, loads.c_side])
    a, b = np.linalg.solve(M, T)
    return float(math.sqrt(math.hypot(a, b))), float(math.atan2(b, a) % math.pi)
