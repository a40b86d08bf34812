"""LQG position controller: steady-state Kalman filter + LQR with integral action.

Design (all on the nominal design model of :mod:`dss14_env.baselines.design`, never on the plant)::

    estimator   x^-_{k+1} = Ad x_k|k + Bd r_k          (r_k the APPLIED command, after the limiter)
                x_k|k     = x^-_k + L (y_k - C x^-_k)  (steady-state Kalman gain, DARE)
    LQR state   z_k = [x_k - x_ref ; xi_k ; r_{k-1} - r_ref]
                xi_{k+1} = xi_k + dt * clip(e_k)       (integral of the servo error, anti-windup clip)
    control     r_k = r_ref - K z_k                    (DARE with a cross term for the action change)

Stage cost of the LQR, per control period, on the environment's normalised quantities
(``sigma_e`` the env's error scale, ``s_a`` its action scale, ``w`` its action-change weight)::

    w_e |e_k / sigma_e|^2 + w_i |xi_k / (sigma_e * 1 s)|^2 + w_a w |(r_k - r_{k-1}) / s_a|^2

``x_ref, r_ref`` put the model on the commanded ramp ``c + c_rate t``
(:meth:`DesignModel.reference_state`), so hold, step and track all use the same law.  With
``w_e = w_a = 1`` and ``w_i = 0`` this is exactly the environment's reward; the small
integral weight removes the offset of the mean wind torque, which the gust model (zero mean)
does not describe.

The Riccati equations are solved by :func:`scipy.linalg.solve_discrete_are`; the residuals are
returned for the tests.  :func:`closed_loop` interconnects any such controller with a
(full-order) plant model and :func:`stationary_performance` gives the exact stationary 3-sigma
servo error and expected per-step cost by a discrete Lyapunov equation.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import linalg

from dss14_env.baselines.base import Controller
from dss14_env.baselines.design import (
    CommandShaper,
    DesignModel,
    LQGConfig,
    ReferenceGenerator,
    build_design_model,
    default_controllers_config,
    infer_wind,
)


# ------------------------------------------------------------------------- Riccati helpers
def dare_residual(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, P: np.ndarray,
                  S: np.ndarray | None = None) -> float:
    """Relative residual of ``P = A'PA - (A'PB + S)(R + B'PB)^-1 (B'PA + S') + Q``.

    :return: ``||residual||_F / max(||P||_F, ||Q||_F)``
    """
    S = np.zeros((A.shape[0], B.shape[1])) if S is None else S
    G = A.T @ P @ B + S
    res = A.T @ P @ A - P - G @ np.linalg.solve(R + B.T @ P @ B, G.T) + Q
    return float(np.linalg.norm(res) / max(np.linalg.norm(P), np.linalg.norm(Q)))


@dataclass(frozen=True)
class Weights:
    """Cost scales taken from the environment: error scale (rad), action scale (rad/s per unit
    action) and the reward's action-change weight."""

    error_scale: float
    action_scale: float
    action_change: float

    def __post_init__(self) -> None:
        for name in ("error_scale", "action_scale"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        if not (math.isfinite(self.action_change) and self.action_change >= 0):
            raise ValueError(f"action_change weight must be >= 0, got {self.action_change!r}")


@dataclass(frozen=True)
class LQGDesign:
    """Gains and Riccati solutions of one LQG design.

    :param dm: the design model
    :param K: LQR gain on ``z = [x - x_ref; xi; r_prev - r_ref]`` (``xi`` absent without
        integral action)
    :param L: Kalman gain (filtered form) of the estimator state ``[x; d]``
    :param P_lqr: LQR Riccati solution
    :param P_kf: Kalman Riccati solution (a-priori error covariance of ``[x; d]``)
    :param n_d: number of input-disturbance states in the estimator (0 or 2)
    :param residuals: relative DARE residuals ``{"lqr": .., "kalman": ..}``
    """

    dm: DesignModel
    K: np.ndarray
    L: np.ndarray
    P_lqr: np.ndarray
    P_kf: np.ndarray
    Az: np.ndarray
    Bz: np.ndarray
    Qz: np.ndarray
    Rz: np.ndarray
    Sz: np.ndarray
    Qn: np.ndarray
    integral: bool
    weights: Weights
    residuals: dict = field(default_factory=dict)
    n_d: int = 0

    @property
    def n_z(self) -> int:
        return self.Az.shape[0]

    def split_gain(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(K_x, K_xi, K_u)``; ``K_xi`` has zero columns without integral action."""
        n = self.dm.n
        ni = 2 if self.integral else 0
        return self.K[:, :n], self.K[:, n:n + ni], self.K[:, n + ni:]


def augmented_lqr_problem(dm: DesignModel, weights: Weights, w_e: float, w_a: float,
                          w_i: float | None) -> tuple[np.ndarray, ...]:
    """Matrices ``(Az, Bz, Qz, Rz, Sz)`` of the LQR on ``z = [x; xi; r_prev]`` (see the module
    docstring); ``w_i=None`` leaves the integrator out (the yardstick)."""
    n, dt = dm.n, dm.dt
    ni = 0 if w_i is None else 2
    nz = n + ni + 2
    Az = np.zeros((nz, nz))
    Bz = np.zeros((nz, 2))
    Az[:n, :n] = dm.Ad
    Bz[:n] = dm.Bd
    if ni:
        Az[n:n + 2, :n] = -dt * dm.C  # xi += dt * e, e = -theta in deviation coordinates
        Az[n:n + 2, n:n + 2] = np.eye(2)
    Bz[n + ni:] = np.eye(2)
    qe = w_e / weights.error_scale ** 2
    qa = w_a * weights.action_change / weights.action_scale ** 2
    Qz = np.zeros((nz, nz))
    Qz[:n, :n] = qe * dm.C.T @ dm.C
    if ni:
        Qz[n:n + 2, n:n + 2] = w_i / weights.error_scale ** 2 * np.eye(2)
    Qz[n + ni:, n + ni:] = qa * np.eye(2)
    # a tiny input weight keeps R > 0 when the env has no action-change penalty
    Rz = (qa + 1e-9 * qe * (dt * weights.action_scale) ** 2) * np.eye(2)
    Sz = np.zeros((nz, 2))
    Sz[n + ni:] = -qa * np.eye(2)
    return Az, Bz, Qz, Rz, Sz


def design_lqg(dm: DesignModel, weights: Weights, w_e: float = 1.0, w_a: float = 1.0,
               w_i: float | None = 1e-3, input_noise: float = 0.0, disturbance_drift: float | None = 0.0,
               rate_limit: float | None = None) -> LQGDesign:
    """LQR (with optional integral action) + steady-state Kalman filter on ``dm``.

    :param dm: design model (:func:`dss14_env.baselines.design.build_design_model`)
    :param weights: the environment's cost scales
    :param w_e: weight on the normalised servo error
    :param w_a: multiplier on the env's action-change weight
    :param w_i: weight on the normalised error integral; ``None``: no integral action
    :param input_noise: extra white noise on the rate command in the Kalman design, standard
        deviation per step as a fraction of ``rate_limit`` (robustness; 0: the pure LQG)
    :param disturbance_drift: ``None``: no disturbance states in the estimator; otherwise the
        estimator carries a constant input disturbance ``d`` (rate-command units, the mean wind
        torque's effect) as a random walk whose step has this standard deviation (fraction of
        ``rate_limit``; 0 is allowed: ``d`` is then set once, at the start, and not estimated)
    :param rate_limit: rad/s, needed when ``input_noise > 0`` or ``disturbance_drift > 0``
    """
    Az, Bz, Qz, Rz, Sz = augmented_lqr_problem(dm, weights, w_e, w_a, w_i)
    # Scale angles (theta, xi) by the error scale and the commands by the action scale so the
    # Riccati solvers see O(1) numbers (an exact similarity, undone below).
    nz = Az.shape[0]
    sz = np.ones(nz)
    sz[:2] = weights.error_scale
    sz[dm.n:nz - 2] = weights.error_scale
    sz[nz - 2:] = weights.action_scale
    su = weights.action_scale
    As = Az * sz[None, :] / sz[:, None]
    Bs = Bz * su / sz[:, None]
    Qs = Qz * np.outer(sz, sz)
    Rs = Rz * su * su
    Ss = Sz * sz[:, None] * su
    Ps = linalg.solve_discrete_are(As, Bs, Qs, Rs, s=Ss)
    Ks = np.linalg.solve(Rs + Bs.T @ Ps @ Bs, Bs.T @ Ps @ As + Ss.T)
    P = Ps / np.outer(sz, sz)
    K = Ks * su / sz[None, :]
    # Kalman filter on [x; d]: process noise = wind increments (+ command noise, + drift of d)
    nd = 0 if disturbance_drift is None or disturbance_drift == 0 else 2
    if (input_noise > 0 or nd) and rate_limit is None:
        raise ValueError("input_noise > 0 or disturbance_drift > 0 needs the rate_limit")
    n = dm.n
    ne = n + nd
    Ae = np.eye(ne)
    Ae[:n, :n] = dm.Ad
    Ae[:n, n:] = dm.Bd if nd else np.zeros((n, 0))
    Ce = np.hstack([dm.C, np.zeros((2, nd))])
    Qn = np.zeros((ne, ne))
    Qn[:n, :n] = dm.Qd
    if input_noise > 0:
        Qn[:n, :n] += (input_noise * rate_limit) ** 2 * dm.Bd @ dm.Bd.T
    if nd:
        Qn[n:, n:] = (disturbance_drift * rate_limit) ** 2 * np.eye(2)
    sx = np.ones(ne)
    sx[:2] = weights.error_scale
    sx[n:] = weights.action_scale
    Ax = Ae * sx[None, :] / sx[:, None]
    Cx = Ce * sx[None, :] / weights.error_scale
    Qx = Qn / np.outer(sx, sx)
    Rx = dm.R / weights.error_scale ** 2
    Pxs = linalg.solve_discrete_are(Ax.T, Cx.T, Qx, Rx)
    Px = Pxs * np.outer(sx, sx)
    L = Px @ Ce.T @ np.linalg.inv(Ce @ Px @ Ce.T + dm.R)
    res = {"lqr": dare_residual(As, Bs, Qs, Rs, Ps, Ss),
           "kalman": dare_residual(Ax.T, Cx.T, Qx, Rx, Pxs)}
    return LQGDesign(dm, K, L, P, Px, Az, Bz, Qz, Rz, Sz, Qn, w_i is not None, weights, res, nd)


# ------------------------------------------------------------------------- analysis
@dataclass(frozen=True)
class LinearController:
    """A discrete LTI controller ``zeta+ = Ac zeta + Bc y``, ``r = Cc zeta + Dc y`` (regulation
    about a constant command; ``y`` the measured encoder angles, rad; ``r`` rad/s)."""

    Ac: np.ndarray
    Bc: np.ndarray
    Cc: np.ndarray
    Dc: np.ndarray


def lqg_as_linear(design: LQGDesign) -> LinearController:
    """The LQG law (hold, no clipping) as one LTI system from ``y`` to ``r``.

    Controller state ``zeta_k = [x^-_k; d^-_k; xi_k; r_{k-1}]`` (``d`` and ``xi`` where the
    design has them); the law is ``r = -d - K_x x - K_xi xi - K_u (r_prev + d)``.  The
    integrator sums the estimated error here (the controller class sums the measured one; in
    the linear analysis the two differ only by the filtered innovation).
    """
    dm = design.dm
    n, nd = dm.n, design.n_d
    ne = n + nd
    Kx, Ki, Ku = design.split_gain()
    ni = Ki.shape[1]
    Lg = design.L
    Ce = np.hstack([dm.C, np.zeros((2, nd))])
    Imlc = np.eye(ne) - Lg @ Ce  # [x; d]_k|k = (I - L C) [x; d]^- + L y
    # r = Fx [x; d]_k|k - Ki xi - Ku r_prev
    Fx = np.hstack([-Kx, -(np.eye(2) + Ku) if nd else np.zeros((2, 0))])
    Cc = np.hstack([Fx @ Imlc, -Ki, -Ku])
    Dc = Fx @ Lg
    nzc = ne + ni + 2
    Ac = np.zeros((nzc, nzc))
    Bc = np.zeros((nzc, 2))
    Ae = np.eye(ne)
    Ae[:n, :n] = dm.Ad
    if nd:
        Ae[:n, n:] = dm.Bd
    Be = np.vstack([dm.Bd, np.zeros((nd, 2))])
    Ac[:ne, :ne] = Ae @ Imlc
    Bc[:ne] = Ae @ Lg
    Ac[:ne] += Be @ Cc
    Bc[:ne] += Be @ Dc
    if ni:
        Ac[ne:ne + ni, :ne] = -dm.dt * Ce @ Imlc
        Ac[ne:ne + ni, ne:ne + ni] = np.eye(ni)
        Bc[ne:ne + ni] = -dm.dt * Ce @ Lg
    Ac[ne + ni:] = Cc
    Bc[ne + ni:] = Dc
    return LinearController(Ac, Bc, Cc, Dc)


@dataclass(frozen=True)
class ClosedLoop:
    """Plant (discrete design model) + linear controller, driven by the plant's process noise
    and the measurement noise.  State ``[x_plant; zeta; r_prev]``."""

    A: np.ndarray
    W: np.ndarray          # covariance of the state noise per step
    C_e: np.ndarray        # servo error e = -theta (hold)
    C_r: np.ndarray        # rate command r_k = C_r X + D_rv v_k
    D_rv: np.ndarray
    C_rprev: np.ndarray
    R: np.ndarray

    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.A)

    def spectral_radius(self) -> float:
        return float(np.max(np.abs(self.eigenvalues())))


def closed_loop(plant: DesignModel, ctrl: LinearController) -> ClosedLoop:
    """Interconnect a plant model with a linear controller (``y = C x + v``).

    The controller's command enters the plant as the held input of the next period; the
    previous command is carried as two extra states so the action change is an output.
    """
    n, nc = plant.n, ctrl.Ac.shape[0]
    Ap, Bp, Cp = plant.Ad, plant.Bd, plant.C
    N = n + nc + 2
    A = np.zeros((N, N))
    A[:n, :n] = Ap + Bp @ ctrl.Dc @ Cp
    A[:n, n:n + nc] = Bp @ ctrl.Cc
    A[n:n + nc, :n] = ctrl.Bc @ Cp
    A[n:n + nc, n:n + nc] = ctrl.Ac
    A[n + nc:, :n] = ctrl.Dc @ Cp
    A[n + nc:, n:n + nc] = ctrl.Cc
    Bv = np.vstack([Bp @ ctrl.Dc, ctrl.Bc, ctrl.Dc])
    Wx = np.zeros((N, N))
    Wx[:n, :n] = plant.Qd
    W = Wx + Bv @ plant.R @ Bv.T
    C_e = np.zeros((2, N))
    C_e[:, :n] = -Cp
    C_r = np.zeros((2, N))
    C_r[:, :n] = ctrl.Dc @ Cp
    C_r[:, n:n + nc] = ctrl.Cc
    C_rprev = np.zeros((2, N))
    C_rprev[:, n + nc:] = np.eye(2)
    return ClosedLoop(A, W, C_e, C_r, ctrl.Dc, C_rprev, plant.R)


def stationary_performance(cl: ClosedLoop, weights: Weights) -> dict[str, Any]:
    """Stationary servo-error statistics and expected per-step cost of a closed loop.

    Solves ``X = A X A' + W`` (:func:`scipy.linalg.solve_discrete_lyapunov`).

    :return: dict with ``three_sigma_mdeg`` ([az, el]), ``rms_mdeg``, ``rate_rms`` (rad/s),
        ``cost`` (expected ``|e/sigma_e|^2 + w |da|^2`` per step), ``cost_error``,
        ``cost_action`` and ``spectral_radius``
    :raises ValueError: if the loop is not asymptotically stable
    """
    rho = cl.spectral_radius()
    if rho >= 1.0:
        raise ValueError(f"closed loop unstable (spectral radius {rho:.6f}): no stationary error")
    X = linalg.solve_discrete_lyapunov(cl.A, cl.W)
    X = 0.5 * (X + X.T)
    var_e = np.diag(cl.C_e @ X @ cl.C_e.T)
    Cd = cl.C_r - cl.C_rprev
    var_da = np.diag(Cd @ X @ Cd.T + cl.D_rv @ cl.R @ cl.D_rv.T) / weights.action_scale ** 2
    var_r = np.diag(cl.C_r @ X @ cl.C_r.T + cl.D_rv @ cl.R @ cl.D_rv.T)
    ce = float(var_e.sum() / weights.error_scale ** 2)
    ca = float(weights.action_change * var_da.sum())
    sig = np.sqrt(var_e) * 180e3 / math.pi
    return {"three_sigma_mdeg": (3 * sig).tolist(), "rms_mdeg": sig.tolist(),
            "rate_rms_rad_s": np.sqrt(var_r).tolist(), "cost": ce + ca, "cost_error": ce,
            "cost_action": ca, "spectral_radius": rho}


# ------------------------------------------------------------------------- the controllers
DEG = math.pi / 180.0
MDEG = math.pi / 180.0e3


@dataclass(frozen=True)
class EnvSpec:
    """What a controller may know about the environment: its interface, not its plant.

    Control period, action scale, command-limiter limits, error scale, the reward's
    action-change weight and the encoder's resolution and noise (sensor specification), all
    SI.  Built from an environment (:meth:`from_env`) or its configuration (:meth:`from_config`).
    """

    dt: float
    action_scale: float
    rate_limit: float
    accel_limit: float
    error_scale: float
    action_change_weight: float
    encoder_bits: int | None
    encoder_noise: float

    @classmethod
    def from_config(cls, cfg: Any) -> "EnvSpec":
        """From a :class:`dss14_env.envs.scenarios.EnvConfig` (or anything with its key names)."""
        return cls(float(cfg.dt), cfg.action_scale_deg_s * DEG, cfg.rate_limit_deg_s * DEG,
                   cfg.accel_limit_deg_s2 * DEG, cfg.error_scale_mdeg * MDEG,
                   float(cfg.action_change_weight), cfg.encoder_bits, cfg.encoder_noise_mdeg * MDEG)

    @classmethod
    def from_env(cls, env: Any) -> "EnvSpec":
        """From a ``DSS14Env`` (wrapped or not)."""
        cfg = getattr(getattr(env, "unwrapped", env), "config", None)
        if cfg is None:
            raise TypeError(f"{env!r} has no DSS14 configuration (.unwrapped.config)")
        return cls.from_config(cfg)

    @classmethod
    def default(cls, **overrides: Any) -> "EnvSpec":
        """From the shipped ``configs/env.yaml`` (keys of it as overrides)."""
        from dss14_env.envs.config import load_env_config
        return cls.from_config(load_env_config(**overrides))

    @property
    def weights(self) -> Weights:
        return Weights(self.error_scale, self.action_scale, self.action_change_weight)

    @property
    def rate_step(self) -> float:
        """Largest change of the rate command per period, rad/s."""
        return self.accel_limit * self.dt


def as_spec(env_or_spec: Any) -> EnvSpec:
    """An :class:`EnvSpec` from an environment, its config, a spec, or ``None`` (defaults)."""
    if env_or_spec is None:
        return EnvSpec.default()
    if isinstance(env_or_spec, EnvSpec):
        return env_or_spec
    if hasattr(env_or_spec, "unwrapped") or hasattr(env_or_spec, "config"):
        return EnvSpec.from_env(env_or_spec)
    return EnvSpec.from_config(env_or_spec)


class ObservationReader:
    """Decode the ``DSS14-v0`` observation (layout in :class:`dss14_env.envs.env.DSS14Env`) to SI.

    :return: of :meth:`read`: ``(y, c, c_rate, r_prev)`` -- encoder reading relative to the
        start (rad), command relative to the start (rad), command rate (rad/s), previous applied
        rate command (rad/s)
    """

    def __init__(self, spec: EnvSpec) -> None:
        self.spec = spec

    def read(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        o = np.asarray(obs, dtype=np.float64)
        if o.shape != (12,):
            raise ValueError(f"expected the 12-element DSS14 observation, got shape {o.shape}")
        if not np.all(np.isfinite(o)):
            raise ValueError(f"observation contains NaN or inf: {o}")
        rl = self.spec.rate_limit
        return o[8:10] * DEG, o[4:6] * DEG, o[6:8] * rl, o[10:12] * rl


class EstimatorController(Controller):
    """Kalman filter + integrator + LQR law; the base of the LQG, MPC and yardstick controllers.

    Per step: predict with the previously APPLIED command (observation 10, 11, so the command
    limiter is accounted for), correct with the encoder reading, build the ramp reference from
    the observed (optionally shaped, :class:`dss14_env.baselines.design.CommandShaper`) command and rate,
    compute the command (:meth:`law`), then advance the integrator with the measured servo
    error clipped to ``integral_clip``.  The first step chooses the episode's design
    (:meth:`select_design`) and initialises bumplessly: the estimate sits on the reference and
    the input disturbance ``d`` takes the observed start command, so the first command equals it.

    :param design: the LQG design (model, gains) used unless :meth:`select_design` picks another
    :param spec: the environment's interface
    :param name: label
    :param integral_clip: anti-windup clip of the integrated error, rad
    :param shaper: command preprocessor (then the reference is a
        :class:`dss14_env.baselines.design.ReferenceGenerator` on the design model), or None (the raw
        command as a ramp)
    :param reference_pull: gain (1/s) pulling the reference model onto the shaped command
    """

    def __init__(self, design: LQGDesign, spec: EnvSpec, name: str,
                 integral_clip: float = math.inf, shaper: Any = None,
                 reference_pull: float = 0.3) -> None:
        super().__init__(name)
        self.reference_pull = float(reference_pull)
        self.spec = spec
        self.reader = ObservationReader(spec)
        self.integral_clip = float(integral_clip)
        self.shaper = shaper
        self.condition = True
        self.reference: ReferenceGenerator | None = None
        self.default_design = design
        self.use_design(design)
        self.reset()

    def use_design(self, design: LQGDesign) -> None:
        """Load the matrices of a design (model, gains, reference maps)."""
        dm = design.dm
        if abs(dm.dt - self.spec.dt) > 1e-12:
            raise ValueError(f"design period {dm.dt} s differs from the env's {self.spec.dt} s")
        self.design = design
        n, nd = dm.n, design.n_d
        self._Ae = np.eye(n + nd)
        self._Ae[:n, :n] = dm.Ad
        if nd:
            self._Ae[:n, n:] = dm.Bd
        self._Be = np.vstack([dm.Bd, np.zeros((nd, 2))])
        self._Ce = np.hstack([dm.C, np.zeros((2, nd))])
        # reference maps: x_ref = Xc c + Xv c_rate + Xa c_acc, r_ref = Rv c_rate + Ra c_acc
        Xc = np.zeros((n, 2))
        Xc[:2] = np.eye(2)
        Xv, Xa = np.zeros((n, 2)), np.zeros((n, 2))
        Rv, Ra = np.zeros((2, 2)), np.zeros((2, 2))
        z2 = np.zeros(2)
        for i in range(2):
            e = np.zeros(2)
            e[i] = 1.0
            Xv[:, i], Rv[:, i] = dm.reference_state(z2, e)
            Xa[:, i], Ra[:, i] = dm.reference_state(z2, z2, e)
        self._Xc, self._Xv, self._Rv, self._Xa, self._Ra = Xc, Xv, Rv, Xa, Ra
        self.Kx, self.Ki, self.Ku = design.split_gain()
        if self.shaper is not None:
            old = self.reference
            K_ref = np.zeros((2, dm.n + 2))
            K_ref[:, :2] = self.reference_pull * np.eye(2)
            self.reference = ReferenceGenerator(dm, self.shaper, K_ref, self.spec.rate_limit,
                                                self.spec.rate_step, accel_ff=1.0)
            if old is not None and old.x is not None:  # switched at the first step
                self.reference.x = None

    def select_design(self, r0: np.ndarray, c_rate0: np.ndarray) -> LQGDesign:
        """The design of this episode, chosen at its first step (default: the fixed one)."""
        return self.default_design

    # -------------------------------------------------------------- state
    def reset(self, seed: int | None = None) -> None:
        """Forget the estimate, the integrator, the shaper and the start command."""
        super().reset(seed)
        self.xe: np.ndarray | None = None   # [x; d] filtered estimate
        self.xi = np.zeros(2)
        self.d_fixed = np.zeros(2)          # start disturbance of a design without d states
        self.n_steps = 0
        if self.reference is not None:
            self.reference.reset()

    def _start(self, y: np.ndarray, c: np.ndarray, cd: np.ndarray, r_prev: np.ndarray) -> None:
        del y  # see below
        t0 = time.perf_counter()
        design = self.select_design(r_prev, cd)
        if design is not self.design:
            self.use_design(design)
        self.info["design_time_s"] = time.perf_counter() - t0
        n, nd = self.design.dm.n, self.design.n_d
        r_ref = self._Rv @ cd  # = the reference generator's first feedforward
        xe = np.zeros(n + nd)
        # the environment starts on the command in steady motion (docs/env.md): the estimate
        # starts on the reference, not on the quantised reading, so the start is bumpless
        xe[:n] = self._Xc @ c + self._Xv @ cd
        if nd:
            xe[n:] = r_ref - r_prev
        else:
            self.d_fixed = r_ref - r_prev
        self.xe = xe

    def _estimate(self, y: np.ndarray, r_prev: np.ndarray) -> None:
        nd = self.design.n_d
        # d enters through Ae when estimated, as a known input otherwise
        prior = self._Ae @ self.xe + self._Be @ (r_prev if nd else r_prev + self.d_fixed)
        self.xe = prior + self.design.L @ (y - self._Ce @ prior)

    def disturbance(self) -> np.ndarray:
        """Current input-disturbance estimate (rad/s, command units)."""
        return self.xe[self.design.dm.n:] if self.design.n_d else self.d_fixed

    def lqr_state(self, c: np.ndarray, cd: np.ndarray, r_prev: np.ndarray,
                  cdd: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(z, r_ss)``: LQR state about the reference (ramp, or parabola with ``cdd``) and
        the command that holds the model on it."""
        n = self.design.dm.n
        x_ref = self._Xc @ c + self._Xv @ cd
        r_ss = self._Rv @ cd - self.disturbance()
        if cdd is not None:
            x_ref = x_ref + self._Xa @ cdd
            r_ss = r_ss + self._Ra @ cdd
        parts = [self.xe[:n] - x_ref]
        if self.design.integral:
            parts.append(self.xi)
        parts.append(r_prev - r_ss)
        return np.concatenate(parts), r_ss

    def deviation(self, x_ref: np.ndarray, r_ff: np.ndarray, r_prev: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """``(z, r_ss)`` about a reference-model state and its feedforward command."""
        n = self.design.dm.n
        r_ss = r_ff - self.disturbance()
        parts = [self.xe[:n] - x_ref]
        if self.design.integral:
            parts.append(self.xi)
        parts.append(r_prev - r_ss)
        return np.concatenate(parts), r_ss

    def _condition(self, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> float:
        """Anti-windup by conditioning the reference (after Hanus et al. 1987).

        If the LQR command ``r_ss - K z`` would be clipped by the limiter, the reference
        model's encoder angles are moved toward the estimate, ``theta_ref += beta (theta^ -
        theta_ref)``, with the smallest ``beta`` in [0, 1] that makes it realisable (as far as
        the shift can; the limiter clips the rest).  The law then asks only for what the drive
        can do and the reference model's pull brings the reference back to the shaped
        command.  Without this the LQG's high gain saturates the acceleration limit and
        limit-cycles (lit. Q4, [DETC99]); the MPC uses the same shift, so a badly mismatched
        plant (randomised parameters) cannot drive it into a constrained limit cycle either.
        Only the angles are shifted: shifting the rate-loop states of the reference model
        would leave it to its own slow (3-5 s) dynamics.

        :return: ``beta`` (the reference is changed in place)
        """
        spec = self.spec
        r = self.lqr_command(z, r_ss)
        lo = np.maximum(r_prev - spec.rate_step, -spec.rate_limit)
        hi = np.minimum(r_prev + spec.rate_step, spec.rate_limit)
        if np.all((r >= lo) & (r <= hi)):
            return 0.0
        delta = self.xe[:2] - self.reference.x[:2]
        g = self.Kx[:, :2] @ delta          # d r / d beta
        beta = 0.0
        for i in range(2):
            target = lo[i] if r[i] < lo[i] else (hi[i] if r[i] > hi[i] else r[i])
            if target != r[i]:
                b = (target - r[i]) / g[i] if g[i] != 0.0 else 0.0
                beta = max(beta, min(b, 1.0))  # b <= 0: the shift cannot help this axis
        self.reference.x[:2] += beta * delta
        return beta

    def lqr_command(self, z: np.ndarray, r_ss: np.ndarray) -> np.ndarray:
        """The LQR law ``r = r_ss - K z`` (rad/s)."""
        return r_ss - self.design.K @ z

    def law(self, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> np.ndarray:
        """The rate command (rad/s); the LQR here, overridden by the MPC."""
        return self.lqr_command(z, r_ss)

    def act(self, observation: np.ndarray) -> np.ndarray:
        """One control period: estimate, build the reference, apply the law (see the class)."""
        t0 = time.perf_counter()
        y, c, cd, r_prev = self.reader.read(observation)
        if self.xe is None:
            self._start(y, c, cd, r_prev)
        else:
            self._estimate(y, r_prev)
        if self.reference is not None:
            x_ref, r_ff = self.reference(c, cd)
            z, r_ss = self.deviation(x_ref, r_ff, r_prev)
            if self.condition:
                beta = self._condition(z, r_ss, r_prev)
                self.info["conditioned"] = beta
                if beta:
                    x_ref = self.reference.x.copy()
                    z, r_ss = self.deviation(x_ref, r_ff, r_prev)
            c_int = x_ref[:2]
        else:
            z, r_ss = self.lqr_state(c, cd, r_prev)
            c_int = c
        r = self.law(z, r_ss, r_prev)
        if self.design.integral:
            self.xi = self.xi + self.spec.dt * np.clip(c_int - y, -self.integral_clip, self.integral_clip)
        self.n_steps += 1
        a = np.clip(r / self.spec.action_scale, -1.0, 1.0)
        self.info["solve_time_s"] = time.perf_counter() - t0
        return a.astype(np.float32)


def lqg_design_from_config(spec: EnvSpec, cfg: LQGConfig | None = None, order: Any = "config",
                           wind: Any = None) -> LQGDesign:
    """The LQG design of ``configs/controllers.yaml`` for an environment interface.

    :param wind: ``None``: the direction-free design wind; ``(speed, direction)``: a coherent gust
    """
    cc = default_controllers_config()
    cfg = cfg or cc.lqg
    noise = math.hypot(spec.encoder_noise, cfg.measurement_noise)
    dm = build_design_model(spec.dt, order=order, wind=wind, encoder_noise=noise,
                            bits=spec.encoder_bits)
    return design_lqg(dm, spec.weights, w_e=cfg.error_weight, w_a=cfg.action_change_weight,
                      w_i=cfg.integral_weight, input_noise=cfg.input_noise,
                      disturbance_drift=cfg.disturbance_drift, rate_limit=spec.rate_limit)


class LQGController(EstimatorController):
    """The reduced-order LQG of ``configs/controllers.yaml`` behind the controller interface.

    With ``wind_model: inferred`` the gust model of each episode is the coherent Davenport gust
    at the design speed from the direction read from the start command
    (:func:`dss14_env.baselines.design.infer_wind`; designs cached per 2 deg); when the inferred speed is
    below ``min_wind_speed`` (no wind) and with ``direction-free`` it is the front+side model.

    :param env: the environment (or its config / an :class:`EnvSpec`; None: shipped defaults)
        -- only its interface is read, never its plant
    :param name: label, default ``"LQG"``
    :param config: LQG settings, default section ``lqg`` of ``configs/controllers.yaml``
    """

    def __init__(self, env: Any = None, name: str = "LQG", config: LQGConfig | None = None) -> None:
        spec = as_spec(env)
        self.config = cfg = config or default_controllers_config().lqg
        self._designs: dict[Any, LQGDesign] = {}
        shaper = (CommandShaper(cfg.shaper_rate, cfg.shaper_accel, spec.dt, cfg.shaper_accel_max)
                  if cfg.shaper else None)
        self.spec = spec
        super().__init__(self._design_for(None), spec, name, cfg.integral_clip, shaper,
                         cfg.reference_pull)

    def _design_for(self, wind: Any) -> LQGDesign:
        if wind not in self._designs:
            self._designs[wind] = lqg_design_from_config(self.spec, self.config, wind=wind)
        return self._designs[wind]

    def wind_key(self, r0: np.ndarray, c_rate0: np.ndarray) -> tuple[float, float] | None:
        """The (rounded) wind of the episode's design, None for the direction-free model."""
        if self.config.wind_model != "inferred":
            return None
        speed, theta = infer_wind(r0, c_rate0)
        if not speed >= self.config.min_wind_speed:
            return None
        step = math.radians(2.0)
        # the direction is exact on the nominal plant; the speed is not (start gust), so the
        # gust model takes the design speed
        return default_controllers_config().design.wind_speed, (round(theta / step) * step) % math.pi

    def select_design(self, r0: np.ndarray, c_rate0: np.ndarray) -> LQGDesign:
        key = self.wind_key(r0, c_rate0)
        self.info["design_wind"] = key
        return self._design_for(key)
