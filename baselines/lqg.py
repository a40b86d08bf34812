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
(:meth:`DesignModel.reference_state`), or on the reference model of
:mod:`dss14_env.baselines.shaping`, so hold, step and track all use the same law.  With
``w_e = w_a = 1`` and ``w_i = 0`` this is exactly the environment's reward; the small
integral weight removes the offset of the mean wind torque, which the gust model (zero mean)
does not describe.

The Riccati equations are solved by :func:`scipy.linalg.solve_discrete_are`; the residuals are
returned for the tests.  The closed-loop analysis of these designs is in
:mod:`dss14_env.baselines.analysis`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import linalg

from dss14_env.baselines.analysis import dare_residual
from dss14_env.baselines.base import (
    Controller,
    check_batch_size,
    check_mask,
    check_observation,
    check_observations,
)
from dss14_env.baselines.design import (
    DesignModel,
    LQGConfig,
    PointingConfig,
    build_design_model,
    default_controllers_config,
    infer_wind,
    rigid_pointing,
    static_deflection_map,
)
from dss14_env.baselines.interface import (
    LIMIT_MARGIN,
    ControlInterface,
    ObservationReader,
    Weights,
    as_interface,
)
from dss14_env.baselines.shaping import FEEDFORWARD_MARGIN, CommandShaper, ReferenceGenerator
from dss14_env.core.threads import single_threaded


# ------------------------------------------------------------------------- design
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
    :param Ce: the estimator's measurement matrix on ``[x; d]``: the encoders' (2 rows), then
        with the monopulse sensor the pointing's ``[Cp, F]`` (el, xel; 4 rows in all)
    :param integral_output: what the integrator sums: the encoder servo error (``"encoder"``)
        or the measured pointing error (``"pointing"``, the monopulse's)
    :param Rm: the measurement noise covariance of ``Ce``'s rows, rad^2
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
    Ce: np.ndarray | None = None
    integral_output: str = "encoder"
    Rm: np.ndarray | None = None

    @property
    def n_z(self) -> int:
        return self.Az.shape[0]

    def split_gain(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(K_x, K_xi, K_u)``; ``K_xi`` has zero columns without integral action."""
        n = self.dm.n
        ni = 2 if self.integral else 0
        return self.K[:, :n], self.K[:, n:n + ni], self.K[:, n + ni:]


def augmented_lqr_problem(dm: DesignModel, weights: Weights, w_e: float, w_a: float,
                          w_i: float | None, w_enc: float = 0.0, integral_output: str = "encoder"
                          ) -> tuple[np.ndarray, ...]:
    """Matrices ``(Az, Bz, Qz, Rz, Sz)`` of the LQR on ``z = [x; xi; r_prev]`` (see the module
    docstring); ``w_i=None`` leaves the integrator out (the yardstick).  The error term scores
    ``dm.Cz`` (the encoder or the pointing error); ``w_enc`` adds the encoder servo error
    with that weight (for a pointing design that should keep the encoders near the command).
    ``integral_output="pointing"`` integrates the pointing error (``dm.Cp``, el and xel)
    instead of the encoder servo error.
    """
    n, dt = dm.n, dm.dt
    ni = 0 if w_i is None else 2
    nz = n + ni + 2
    Az = np.zeros((nz, nz))
    Bz = np.zeros((nz, 2))
    Az[:n, :n] = dm.Ad
    Bz[:n] = dm.Bd
    if ni:
        # xi += dt * e, e = -theta (or -pointing) in deviation coordinates
        Az[n:n + 2, :n] = -dt * (dm.Cp if integral_output == "pointing" else dm.C)
        Az[n:n + 2, n:n + 2] = np.eye(2)
    Bz[n + ni:] = np.eye(2)
    qe = w_e / weights.error_scale ** 2
    qa = w_a * weights.action_change / weights.action_scale ** 2
    Qz = np.zeros((nz, nz))
    Qz[:n, :n] = qe * dm.Cz.T @ dm.Cz + w_enc / weights.error_scale ** 2 * dm.C.T @ dm.C
    if ni:
        Qz[n:n + 2, n:n + 2] = w_i / weights.error_scale ** 2 * np.eye(2)
    Qz[n + ni:, n + ni:] = qa * np.eye(2)
    # a tiny input weight keeps R > 0 when the env has no action-change penalty
    Rz = (qa + 1e-9 * qe * (dt * weights.action_scale) ** 2) * np.eye(2)
    Sz = np.zeros((nz, 2))
    Sz[n + ni:] = -qa * np.eye(2)
    return Az, Bz, Qz, Rz, Sz


@single_threaded
def design_lqg(dm: DesignModel, weights: Weights, w_e: float = 1.0, w_a: float = 1.0,
               w_i: float | None = 1e-3, input_noise: float = 0.0, disturbance_drift: float | None = 0.0,
               rate_limit: float | None = None, w_enc: float = 0.0, pointing_noise: float | None = None
               ) -> LQGDesign:
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
    :param w_enc: extra weight on the normalised encoder servo error when ``dm`` scores the
        pointing (:func:`augmented_lqr_problem`)
    :param pointing_noise: None: the encoders only; otherwise the Kalman filter also measures
        the dish's pointing ``Cp x + F d`` (the monopulse sensor; ``F`` the static deflection
        of ``d``, :func:`dss14_env.baselines.design.static_deflection_map`) with white noise of
        this standard deviation per step (rad), and the integrator sums the measured pointing
        error (needs a model with the pointing outputs)
    """
    integral_output = "encoder" if pointing_noise is None else "pointing"
    Az, Bz, Qz, Rz, Sz = augmented_lqr_problem(dm, weights, w_e, w_a, w_i, w_enc, integral_output)
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
    Ce, Rm = dm.estimator_output(nd), dm.R
    if pointing_noise is not None:
        Ce = np.vstack([Ce, np.hstack([dm.Cp, static_deflection_map()[:, :nd]])])
        Rm = linalg.block_diag(dm.R, pointing_noise ** 2 * np.eye(2))
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
    Rx = Rm / weights.error_scale ** 2
    Pxs = linalg.solve_discrete_are(Ax.T, Cx.T, Qx, Rx)
    Px = Pxs * np.outer(sx, sx)
    L = Px @ Ce.T @ np.linalg.inv(Ce @ Px @ Ce.T + Rm)
    res = {"lqr": dare_residual(As, Bs, Qs, Rs, Ps, Ss),
           "kalman": dare_residual(Ax.T, Cx.T, Qx, Rx, Pxs)}
    return LQGDesign(dm, K, L, P, Px, Az, Bz, Qz, Rz, Sz, Qn, w_i is not None, weights, res, nd, Ce,
                     integral_output, Rm)


# ------------------------------------------------------------------------- analysis


# ------------------------------------------------------------------------- the controllers
@dataclass(frozen=True)
class DesignMaps:
    """One design as the controller applies it to rows (row vectors: ``x_next = x @ Ae.T``).

    ``Ae, Be, Ce``: estimator model on ``[x; d]``; reference maps ``x_ref = Xc c + Xv c_rate``,
    ``r_ref = Rv c_rate``; ``Kx`` the LQR gain's state block; ``reference`` the reference model
    (None without a command shaper).  ``Hx, Hd``: for a pointing design or axis encoders, the
    shift of the reference's drive angles that puts the dish's pointing (not the drives) on the
    command, ``theta_ref += x_ref Hx + d Hd`` (:meth:`reference_shift`); None for an encoder
    design on drive encoders.  ``Dm``: the measurement's static part per unit ``d``
    (:meth:`dss14_env.baselines.design.DesignModel.disturbance_measurement`).
    """

    design: LQGDesign
    Ae: np.ndarray
    Be: np.ndarray
    Ce: np.ndarray
    Xc: np.ndarray
    Xv: np.ndarray
    Rv: np.ndarray
    Kx: np.ndarray
    reference: ReferenceGenerator | None
    Hx: np.ndarray | None = None
    Hd: np.ndarray | None = None
    Dm: np.ndarray | None = None
    Dy: np.ndarray | None = None

    def reference_shift(self, x_ref: np.ndarray, dist: np.ndarray) -> np.ndarray | None:
        """The encoder-angle shift ``(k, 2)`` (rad) of the rows' reference states ``x_ref`` under
        the command-level disturbances ``dist`` (``(k, 2)``, rad/s); None for an encoder design.

        The pointing is ``S theta + deformation``; the reference's deformation is the model's,
        ``Cd x_ref`` (a ramp bends the structure), plus the static deflection ``F d`` of the mean
        wind torque that the model represents as the command offset ``d``
        (:func:`dss14_env.baselines.design.static_deflection_map`).  The shift
        ``-S^-1 (Cd x_ref + F d)`` makes ``S theta_ref + deformation = S c``.
        """
        if self.Hx is None:
            return None
        return x_ref @ self.Hx + dist @ self.Hd

    @classmethod
    def build(cls, design: LQGDesign, interface: ControlInterface, shaped: bool,
              reference_pull: float, reference_accel_share: float = FEEDFORWARD_MARGIN) -> DesignMaps:
        """The maps of ``design``; with ``shaped`` the reference model pulls onto the shaped
        command with ``reference_pull`` (1/s), its feedforward using at most
        ``reference_accel_share`` of the limiter's acceleration.

        :raises ValueError: if the design's period is not the environment's
        """
        dm = design.dm
        if abs(dm.dt - interface.dt) > 1e-12:
            raise ValueError(f"design period {dm.dt} s differs from the env's {interface.dt} s")
        n, nd = dm.n, design.n_d
        Ae = np.eye(n + nd)
        Ae[:n, :n] = dm.Ad
        if nd:
            Ae[:n, n:] = dm.Bd
        Be = np.vstack([dm.Bd, np.zeros((nd, 2))])
        Ce = dm.estimator_output(nd) if design.Ce is None else design.Ce
        Dm = dm.disturbance_measurement()
        Dy = Dm if Ce.shape[0] == 2 else np.vstack([Dm, static_deflection_map()])
        Xc = np.zeros((n, 2))
        Xc[:2] = np.eye(2)
        Xv, Rv = np.zeros((n, 2)), np.zeros((2, 2))
        for i, e in enumerate(np.eye(2)):
            Xv[:, i], Rv[:, i] = dm.reference_state(np.zeros(2), e)
        reference = None
        if shaped:
            K_ref = np.zeros((2, n + 2))
            K_ref[:, :2] = reference_pull * np.eye(2)
            reference = ReferenceGenerator(dm, K_ref, interface.rate_limit, interface.rate_step,
                                           accel_ff=1.0, accel_margin=reference_accel_share)
        Hx = Hd = None
        if dm.error_output == "pointing" or dm.encoders == "axis":
            Sinv_T = np.linalg.inv(rigid_pointing(dm.xel_scale)).T
            Hx = -dm.deformation_map().T @ Sinv_T
            Hd = -static_deflection_map().T @ Sinv_T
        return cls(design, Ae, Be, Ce, Xc, Xv, Rv, design.split_gain()[0], reference, Hx, Hd, Dm, Dy)

    def measured_reference(self, x_ref: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """What the encoders read ``(k, 2)`` at the rows' reference states ``x_ref`` under the
        disturbances ``dist``: the integrator's target (the command, for axis encoders; the
        shifted drive angles, for a pointing design on drive encoders).
        """
        return x_ref @ self.design.dm.C.T + dist @ self.Dm.T


class EstimatorController(Controller):
    """Kalman filter + integrator + LQR law; the base of the LQG, MPC and yardstick controllers.

    Per step and row: predict with the previously APPLIED command (observation 10, 11, so the
    command limiter is accounted for), correct with the encoder reading, build the reference --
    the raw command as a ramp, or (with a shaper) the reference model driven along the shaped
    command -- compute the command (:meth:`law_rows`, :meth:`law`), then advance the integrator
    with the measured servo error clipped to ``integral_clip``.  A row's first step chooses its
    episode's design (:meth:`select_designs`) and initialises bumplessly: the estimate sits on
    the reference and the input disturbance ``d`` takes the observed start command, so the first
    command equals it.  Rows with the same design are computed together (batchable: every row is
    an independent controller, see :class:`dss14_env.baselines.base.Controller`).

    Anti-windup by conditioning (R. Hanus, M. Kinnaert, J.-L. Henrotte, "Conditioning technique,
    a general anti-windup and bumpless transfer method", Automatica 23(6), 1987): if the LQR
    command ``r_ss - K z`` would be clipped by the limiter, the reference model's encoder angles
    are moved toward the estimate, ``theta_ref += beta (theta^ - theta_ref)``, with the smallest
    ``beta`` in [0, 1] that makes it realisable (as far as the shift can; the limiter clips the
    rest).  The law then asks only for what the drive can do and the reference model's pull
    brings the reference back to the shaped command.  Without it the LQG's high gain saturates
    the acceleration limit and limit-cycles; the MPC uses the same shift, so a badly mismatched
    plant (randomised parameters) cannot drive it into a constrained limit cycle either.  Only
    the angles are shifted: shifting the rate-loop states of the reference model would leave it
    to its own slow (3-5 s) dynamics.  ``info["conditioned"]`` is ``beta``.

    :param design: the LQG design (model, gains) used unless :meth:`select_designs` picks another
    :param interface: the environment's interface
    :param name: label
    :param integral_clip: anti-windup clip of the integrated error, rad
    :param shaper: command preprocessor (then the reference is a
        :class:`dss14_env.baselines.shaping.ReferenceGenerator` on the design model), or None
        (the raw command as a ramp)
    :param reference_pull: gain (1/s) pulling the reference model onto the shaped command
    :param reference_accel_share: share of the limiter's acceleration the reference model's
        feedforward may use; the rest is the feedback's
    """

    batchable = True

    def __init__(self, design: LQGDesign, interface: ControlInterface, name: str,
                 integral_clip: float = math.inf, shaper: CommandShaper | None = None,
                 reference_pull: float = 0.3,
                 reference_accel_share: float = FEEDFORWARD_MARGIN) -> None:
        super().__init__(name)
        self.interface = interface
        self.reader = ObservationReader(interface)
        self.integral_clip = float(integral_clip)
        self.shaper = shaper
        self.reference_pull = float(reference_pull)
        self.reference_accel_share = float(reference_accel_share)
        self.default_design = design
        self._law_design = design           # the design :meth:`law` applies (set per group)
        self._maps: dict[int, DesignMaps] = {}
        self.maps(design)
        self.reset()

    def maps(self, design: LQGDesign) -> DesignMaps:
        """The :class:`DesignMaps` of a design (built once per design)."""
        key = id(design)
        if key not in self._maps:
            self._maps[key] = DesignMaps.build(design, self.interface, self.shaper is not None,
                                               self.reference_pull, self.reference_accel_share)
        return self._maps[key]

    def select_designs(self, rows: np.ndarray, r0: np.ndarray, c_rate0: np.ndarray) -> list[LQGDesign]:
        """The designs of the episodes that start in ``rows``, from their start commands
        ``r0`` and command rates ``c_rate0`` (``(k, 2)``, rad/s); default: the fixed one.
        """
        return [self.default_design] * len(rows)

    # -------------------------------------------------------------- episodes
    def _allocate(self, n: int) -> None:
        self.n = n
        self._designs: list[LQGDesign] = [self.default_design] * n
        self._groups: list[tuple[DesignMaps, np.ndarray]] | None = None
        self._xe = np.zeros((n, 0))         # [x; d] filtered estimate
        self._xr = np.zeros((n, 0))         # reference-model state
        self._rr = np.zeros((n, 2))         # reference-model command (feedforward)
        self._d_fixed = np.zeros((n, 2))    # start disturbance of a design without d states
        self._xi = np.zeros((n, 2))         # error integral
        self._k = np.zeros(n, np.int64)     # steps of the rows' episodes so far
        self._fresh = np.ones(n, bool)
        if self.shaper is not None:
            self.shaper.reset(n)

    def reset(self, seed: int | None = None) -> None:
        """Forget the estimate, the integrator, the shaper and the start command."""
        super().reset(seed)
        self._allocate(1)

    def reset_batch(self, n: int, seeds: Sequence[int] | None = None) -> None:
        """Start ``n`` episodes (rows); ``seeds`` unused (the controller is deterministic)."""
        if not self.batchable:
            super().reset_batch(n, seeds)
        self._allocate(check_batch_size(n, seeds))
        self.info_batch = {}

    def restart(self, mask: np.ndarray) -> None:
        """The rows ``mask`` start a new episode (and choose its design) at the next
        :meth:`act_batch`.
        """
        if not self.batchable:
            super().restart(mask)
        m = check_mask(mask, self.n)
        self._fresh |= m
        if self.shaper is not None:
            self.shaper.restart(m)

    @property
    def design(self) -> LQGDesign:
        """The design of the (first row's) episode."""
        return self._designs[0]

    @property
    def designs(self) -> list[LQGDesign]:
        """The designs of the rows' episodes (chosen at their first step)."""
        return list(self._designs)

    def _start_rows(self, rows: np.ndarray, c: np.ndarray, cd: np.ndarray, r_prev: np.ndarray) -> None:
        """Choose the designs of the rows starting an episode and initialise them bumplessly:
        the environment starts on the command in steady motion (docs/env.md), so the estimate
        starts on the reference, not on the quantised reading.
        """
        for i, d in zip(rows.tolist(), self.select_designs(rows, r_prev[rows], cd[rows]), strict=True):
            self._designs[i] = d
        self._groups = None
        width = max(d.dm.n + d.n_d for d in self._designs)
        if self._xe.shape[1] < width:
            self._xe = np.hstack([self._xe, np.zeros((self.n, width - self._xe.shape[1]))])
            self._xr = np.hstack([self._xr, np.zeros((self.n, width - self._xr.shape[1]))])
        for M, idx in self._group(rows):
            n, nd = M.design.dm.n, M.design.n_d
            r_ref = cd[idx] @ M.Rv.T
            self._xe[idx, :n] = c[idx] @ M.Xc.T + cd[idx] @ M.Xv.T
            self._xe[idx, n:n + nd] = r_ref - r_prev[idx]
            self._d_fixed[idx] = 0.0 if nd else r_ref - r_prev[idx]
            if M.design.dm.encoders == "axis":
                # the start holds the AXIS encoders on the command: the drives sit off it by the
                # deflection of the reference motion and of the mean torque
                self._xe[idx, :2] += M.reference_shift(self._xe[idx, :n], r_ref - r_prev[idx])
        self._xi[rows] = 0.0
        self._k[rows] = 0

    def _group(self, rows: np.ndarray | None = None) -> list[tuple[DesignMaps, np.ndarray]]:
        """``(maps, row indices)`` per design among ``rows`` (default: all, cached)."""
        if rows is None and self._groups is not None:
            return self._groups
        sel = np.arange(self.n) if rows is None else rows
        ids = np.array([id(self._designs[i]) for i in sel.tolist()])
        out = [(self.maps(self._designs[int(sel[np.argmax(ids == key)])]), sel[ids == key])
               for key in dict.fromkeys(ids.tolist())]
        if rows is None:
            self._groups = out
        return out

    # -------------------------------------------------------------- control
    def lqr_command(self, design: LQGDesign, z: np.ndarray, r_ss: np.ndarray) -> np.ndarray:
        """The LQR law ``r = r_ss - K z`` (rad/s) for rows ``z`` ``(k, n_z)``."""
        return r_ss - z @ design.K.T

    def law_rows(self, design: LQGDesign, rows: np.ndarray, z: np.ndarray, r_ss: np.ndarray,
                 r_prev: np.ndarray) -> np.ndarray:
        """The rate commands (rad/s) of the rows ``rows`` of one design (``z`` ``(k, n_z)``,
        ``r_ss`` and ``r_prev`` ``(k, 2)``): the LQR for all of them at once, or :meth:`law`
        row by row where a subclass overrides that (the MPC overrides this method).
        """
        if type(self).law is EstimatorController.law:
            return self.lqr_command(design, z, r_ss)
        self._law_design = design
        return np.array([self.law(z[j], r_ss[j], r_prev[j]) for j in range(len(rows))])

    def law(self, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> np.ndarray:
        """The rate command (rad/s) of one row (``z`` ``(n_z,)``, ``r_ss``, ``r_prev`` ``(2,)``):
        the LQR of the row's design; the hook a subclass overrides to see or change the law one
        row at a time.
        """
        return r_ss - self._law_design.K @ z

    @property
    def Kx(self) -> np.ndarray:
        """The LQR gain's block on the model state, of :attr:`design`."""
        return self.design.split_gain()[0]

    @property
    def Ki(self) -> np.ndarray:
        """The LQR gain's block on the error integral (no columns without one), of :attr:`design`."""
        return self.design.split_gain()[1]

    @property
    def Ku(self) -> np.ndarray:
        """The LQR gain's block on the previous command, of :attr:`design`."""
        return self.design.split_gain()[2]

    def disturbance(self, row: int = 0) -> np.ndarray:
        """The input-disturbance estimate ``d`` of a row (rad/s, command units): the mean wind
        torque's effect.
        """
        D = self._designs[row]
        n, nd = D.dm.n, D.n_d
        return self._xe[row, n:n + nd].copy() if nd else self._d_fixed[row].copy()

    @staticmethod
    def _deviation(design: LQGDesign, xe: np.ndarray, x_ref: np.ndarray, r_ff: np.ndarray,
                   dist: np.ndarray, xi: np.ndarray, r_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(z, r_ss)``: LQR state about a reference state and its feedforward command."""
        r_ss = r_ff - dist
        parts = [xe[:, :design.dm.n] - x_ref] + ([xi] if design.integral else []) + [r_prev - r_ss]
        return np.concatenate(parts, axis=1), r_ss

    def _condition(self, M: DesignMaps, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray,
                   xe: np.ndarray, x_ref: np.ndarray) -> np.ndarray:
        """Conditioning ``beta`` per row (see the class); shifts ``x_ref`` in place."""
        ci = self.interface
        r = self.lqr_command(M.design, z, r_ss)
        step, limit = ci.rate_step * (1.0 - LIMIT_MARGIN), ci.rate_limit * (1.0 - LIMIT_MARGIN)
        lo = np.maximum(r_prev - step, -limit)
        hi = np.minimum(r_prev + step, limit)
        viol = (r < lo) | (r > hi)
        beta = np.zeros(len(r))
        rows = np.flatnonzero(viol.any(axis=1))
        if rows.size == 0:
            return beta
        delta = xe[rows, :2] - x_ref[rows, :2]
        g = delta @ M.Kx[:, :2].T            # d r / d beta
        rv = r[rows]
        target = np.clip(rv, lo[rows], hi[rows])
        with np.errstate(divide="ignore", invalid="ignore"):
            b = np.where(g != 0.0, (target - rv) / g, 0.0)
        b = np.where(viol[rows], np.minimum(b, 1.0), -np.inf)  # b <= 0: the shift cannot help
        beta[rows] = np.maximum(b.max(axis=1), 0.0)
        x_ref[rows, :2] += beta[rows, None] * delta
        return beta

    def _step_group(self, M: DesignMaps, idx: np.ndarray, fresh: np.ndarray, y: np.ndarray,
                    c: np.ndarray, cd: np.ndarray, r_prev: np.ndarray,
                    shaped: tuple[np.ndarray, ...] | None) -> tuple[np.ndarray, np.ndarray]:
        """One period for the rows ``idx`` of one design; returns ``(r, beta)``."""
        D = M.design
        n, ne = D.dm.n, D.dm.n + D.n_d
        xe, xi = self._xe[idx, :ne], self._xi[idx]
        est = ~fresh
        if est.any():
            # d enters through Ae when estimated, as a known input otherwise
            u = r_prev[est] if D.n_d else r_prev[est] + self._d_fixed[idx][est]
            prior = xe[est] @ M.Ae.T + u @ M.Be.T
            y_est = y[est] if D.n_d else y[est] - self._d_fixed[idx][est] @ M.Dy.T
            xe[est] = prior + (y_est - prior @ M.Ce.T) @ D.L.T
        dist = xe[:, n:] if D.n_d else self._d_fixed[idx]
        beta = np.zeros(len(idx))
        if M.reference is not None:
            cs, vs, acc = (a[idx] for a in shaped)
            x_ref, r_ff = np.empty((len(idx), n)), np.empty((len(idx), 2))
            if fresh.any():
                x_ref[fresh], r_ff[fresh] = M.reference.start(cs[fresh], vs[fresh], acc[fresh])
            if est.any():
                x_ref[est], r_ff[est] = M.reference.advance(self._xr[idx, :n][est], self._rr[idx][est],
                                                            cs[est], vs[est], acc[est])
            shift = M.reference_shift(x_ref, dist)
            if shift is not None:
                x_ref[:, :2] += shift
            z, r_ss = self._deviation(D, xe, x_ref, r_ff, dist, xi, r_prev)
            beta = self._condition(M, z, r_ss, r_prev, xe, x_ref)
            z, r_ss = self._deviation(D, xe, x_ref, r_ff, dist, xi, r_prev)
            c_int = self._integral_target(M, x_ref, dist, shift)
            if shift is not None:
                x_ref[:, :2] -= shift  # the reference model runs on the command, unshifted
            self._xr[idx, :n], self._rr[idx] = x_ref, r_ff
        else:
            x_ref = c @ M.Xc.T + cd @ M.Xv.T
            shift = M.reference_shift(x_ref, dist)
            if shift is not None:
                x_ref[:, :2] += shift
            z, r_ss = self._deviation(D, xe, x_ref, cd @ M.Rv.T, dist, xi, r_prev)
            c_int = self._integral_target(M, x_ref, dist, shift)
        r = self.law_rows(D, idx, z, r_ss, r_prev)
        if D.integral:
            y_int = y[:, 2:4] if D.integral_output == "pointing" else y[:, :2]
            self._xi[idx] = xi + self.interface.dt * np.clip(c_int - y_int, -self.integral_clip,
                                                             self.integral_clip)
        self._xe[idx, :ne] = xe
        return r, beta

    @staticmethod
    def _integral_target(M: DesignMaps, x_ref: np.ndarray, dist: np.ndarray, shift: np.ndarray | None
                         ) -> np.ndarray:
        """What the integrator holds the measurement to, for the rows' (shifted) reference
        states: the encoders' reading of it (:meth:`DesignMaps.measured_reference`), or for a
        design that integrates the pointing, the pointing of the unshifted reference angles.
        """
        if M.design.integral_output != "pointing":
            return M.measured_reference(x_ref, dist)
        theta = x_ref[:, :2] if shift is None else x_ref[:, :2] - shift
        return theta @ rigid_pointing(M.design.dm.xel_scale).T

    def measurement(self, obs: np.ndarray, y: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The Kalman filter's measurement of the rows ``(n, p)``: the encoder readings ``y``
        (rad, relative to the start); a controller with more sensors appends theirs (``obs``
        the checked observations, ``c`` the commands, rad).
        """
        return y

    def _step(self, obs: np.ndarray) -> np.ndarray:
        """One period for all rows; ``obs`` checked, float64 ``(n, 12)`` (or ``(n, 14)``)."""
        t0 = time.perf_counter()
        y, c, cd, r_prev = self.reader.read(obs)
        y = self.measurement(obs, y, c)
        fresh = self._fresh.copy()
        if fresh.any():
            self._start_rows(np.flatnonzero(fresh), c, cd, r_prev)
            self._fresh[:] = False
        shaped = self.shaper(c, cd) if self.shaper is not None else None
        r, beta = np.zeros((self.n, 2)), np.zeros(self.n)
        for M, idx in self._group():
            r[idx], beta[idx] = self._step_group(M, idx, fresh[idx], y[idx], c[idx], cd[idx],
                                                 r_prev[idx], shaped)
        self._k += 1
        a = np.clip(r / self.interface.action_scale, -1.0, 1.0).astype(np.float32)
        self.info_batch = {"rate_command_rad_s": r, "conditioned": beta, **self.row_info(),
                           "solve_time_s": np.full(self.n, (time.perf_counter() - t0) / self.n)}
        return a

    def row_info(self) -> dict[str, np.ndarray]:
        """Per-row entries of :attr:`info_batch` that subclasses add (none here)."""
        return {}

    def episode_info(self) -> dict[str, Any]:
        """Entries of :attr:`info` that describe the episode so far (none here)."""
        return {}

    def act(self, observation: np.ndarray) -> np.ndarray:
        """One control period of one episode (see the class).

        :raises ValueError: on a wrong-shape or non-finite observation, or after
            :meth:`reset_batch` with more than one row
        """
        obs = check_observation(observation)
        if self.n != 1:
            raise ValueError(f"act() runs one episode, but the controller runs a batch of {self.n}; "
                             "use act_batch or reset()")
        t0 = time.perf_counter()
        a = self._step(obs[None])[0]
        self.info = {**{k: v[0] for k, v in self.info_batch.items()}, **self.episode_info(),
                     "solve_time_s": time.perf_counter() - t0}
        return a

    def act_batch(self, observations: np.ndarray) -> np.ndarray:
        """Actions ``(n, 2)`` for the rows' observations ``(n, 12)``; per-row information
        (``rate_command_rad_s``, ``conditioned``, ``solve_time_s``, ...) in :attr:`info_batch`.

        :raises ValueError: on a wrong shape or a non-finite entry
        """
        if not self.batchable:
            super().act_batch(observations)
        return self._step(check_observations(observations, self.n))


def lqg_design_from_config(interface: ControlInterface, cfg: LQGConfig | None = None,
                           order: Any = "config", wind: Any = None,
                           pointing: PointingConfig | None = None,
                           pointing_noise: float | None = None) -> LQGDesign:
    """The LQG design of ``configs/controllers.yaml`` for an environment interface.

    :param wind: ``None``: the direction-free design wind; ``(speed, direction)``: a coherent gust
    :param pointing: ``None``: the encoder design (section ``lqg``); a :class:`PointingConfig`:
        the pointing design -- the error term scores the dish's pointing error plus the
        section's encoder weight, the action-change multiplier and (with ``order="config"``)
        the reduced order are the section's, everything else is ``cfg``'s
    :param pointing_noise: with a pointing design, the Kalman filter also measures the pointing
        (the monopulse sensor) with this noise std per step, rad (:func:`design_lqg`)

    A process designs each combination of these arguments once (:func:`cached_lqg_design`); the
    design is shared, its arrays read-only.
    """
    key = (interface, cfg or default_controllers_config().lqg, order, wind, pointing, pointing_noise)
    try:
        hash(key)
    except TypeError:  # e.g. a wind given as a list: designed every time
        return _design_from_config(*key)
    return cached_lqg_design(*key)


#: LQG designs a process keeps (:func:`cached_lqg_design`), the least recently used dropped first
LQG_DESIGNS_KEPT = 256


def _read_only(design: LQGDesign) -> LQGDesign:
    """``design`` with its arrays made read-only (a shared design no caller may change)."""
    for f in dataclasses.fields(design):
        value = getattr(design, f.name)
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
    return design


@functools.lru_cache(maxsize=LQG_DESIGNS_KEPT)
def cached_lqg_design(interface: ControlInterface, cfg: LQGConfig, order: Any, wind: Any,
                      pointing: PointingConfig | None, pointing_noise: float | None) -> LQGDesign:
    """:func:`lqg_design_from_config`'s design, computed once per process for each combination
    of its (hashable) arguments and shared, its arrays read-only (``cache_clear()`` forgets
    them).
    """
    return _read_only(_design_from_config(interface, cfg, order, wind, pointing, pointing_noise))


def _design_from_config(interface: ControlInterface, cfg: LQGConfig, order: Any, wind: Any,
                        pointing: PointingConfig | None, pointing_noise: float | None) -> LQGDesign:
    """The design of :func:`lqg_design_from_config`, computed."""
    noise = math.hypot(interface.encoder_noise, cfg.measurement_noise)
    w_a = cfg.axis_action_change_weight if interface.encoders == "axis" else cfg.action_change_weight
    w_enc, error_output = 0.0, "encoder"
    if order == "config" and (pointing is not None or interface.encoders == "axis"):
        # the deformation is in the cost or in the measurement: the order that balances it
        order = default_controllers_config().pointing.order
    if pointing is not None:
        w_a, w_enc, error_output = pointing.action_change_weight, pointing.encoder_error_weight, "pointing"
    dm = build_design_model(interface.dt, order=order, wind=wind, encoder_noise=noise,
                            bits=interface.encoder_bits, error_output=error_output,
                            encoders=interface.encoders)
    return design_lqg(dm, interface.weights, w_e=cfg.error_weight, w_a=w_a,
                      w_i=cfg.integral_weight, input_noise=cfg.input_noise,
                      disturbance_drift=cfg.disturbance_drift, rate_limit=interface.rate_limit,
                      w_enc=w_enc, pointing_noise=pointing_noise)


#: the inferred wind directions are rounded to this step for the design cache, rad
DIRECTION_STEP = math.radians(2.0)


class LQGController(EstimatorController):
    """The reduced-order LQG of ``configs/controllers.yaml`` behind the controller interface.

    With ``wind_model: inferred`` the gust model of each episode is the coherent Davenport gust
    at the design speed from the direction read from the start command
    (:func:`dss14_env.baselines.design.infer_wind`; designs cached per 2 deg, rows of a batch
    with different directions use different designs); when the inferred speed is below
    ``min_wind_speed`` (no wind) and with ``direction-free`` it is the front+side model.
    ``info["design_wind"]`` is the episode's ``(speed, direction)`` or None (``info_batch``:
    ``design_wind_speed_mps`` and ``design_wind_direction_rad``, NaN for None).

    :param env: the environment (or its config / a :class:`ControlInterface`; None: shipped
        defaults) -- only its interface is read, never its plant
    :param name: label, default ``"LQG"``
    :param config: LQG settings, default section ``lqg`` of ``configs/controllers.yaml``
    :param pointing: None (the encoder design) or the pointing design's settings (section
        ``pointing``; :func:`lqg_design_from_config`, :class:`PointingLQGController`)
    :param pointing_noise: with ``pointing``, the Kalman filter also measures the pointing (the
        monopulse sensor, :class:`dss14_env.baselines.monopulse.MonopulseLQGController`) with
        this noise std per step, rad; None: the encoders only
    """

    def __init__(self, env: Any = None, name: str = "LQG", config: LQGConfig | None = None,
                 pointing: PointingConfig | None = None, *, pointing_noise: float | None = None) -> None:
        interface = as_interface(env)
        self.pointing = pointing
        self.pointing_noise = pointing_noise
        self.config = cfg = config or default_controllers_config().lqg
        self._designs_by_wind: dict[Any, LQGDesign] = {}
        self.interface = interface
        shaper = (CommandShaper(cfg.shaper_rate, cfg.shaper_accel, interface.dt, cfg.shaper_accel_max)
                  if cfg.shaper else None)
        super().__init__(self.design_for(None), interface, name, cfg.integral_clip, shaper,
                         cfg.reference_pull, cfg.reference_accel_share)

    def design_for(self, wind: Any) -> LQGDesign:
        """The design for a wind key (:meth:`wind_key`; cached)."""
        if wind not in self._designs_by_wind:
            self._designs_by_wind[wind] = lqg_design_from_config(self.interface, self.config, wind=wind,
                                                                 pointing=self.pointing,
                                                                 pointing_noise=self.pointing_noise)
        return self._designs_by_wind[wind]

    def wind_key(self, r0: np.ndarray, c_rate0: np.ndarray) -> tuple[float, float] | None:
        """The (rounded) wind of an episode's design, None for the direction-free model."""
        if self.config.wind_model != "inferred":
            return None
        speed, theta = infer_wind(r0, c_rate0)
        if not speed >= self.config.min_wind_speed:
            return None
        # the direction is exact on the nominal plant; the speed is not (start gust), so the
        # gust model takes the design speed
        return (default_controllers_config().design.wind_speed,
                (round(theta / DIRECTION_STEP) * DIRECTION_STEP) % math.pi)

    def _allocate(self, n: int) -> None:
        super()._allocate(n)
        self._wind_keys: list[tuple[float, float] | None] = [None] * n

    def select_designs(self, rows: np.ndarray, r0: np.ndarray, c_rate0: np.ndarray) -> list[LQGDesign]:
        out = []
        for i, r, v in zip(rows.tolist(), r0, c_rate0, strict=True):
            self._wind_keys[i] = key = self.wind_key(r, v)
            out.append(self.design_for(key))
        return out

    def row_info(self) -> dict[str, np.ndarray]:
        w = np.array([(math.nan, math.nan) if k is None else k for k in self._wind_keys], float)
        return {"design_wind_speed_mps": w[:, 0], "design_wind_direction_rad": w[:, 1]}

    def episode_info(self) -> dict[str, Any]:
        return {"design_wind": self._wind_keys[0]}


class PointingLQGController(LQGController):
    """The LQG designed for the dish's true pointing error (``lqg_pointing``).

    Everything as :class:`LQGController` (Kalman filter on the drive encoders, wind inference,
    shaper, integrator, conditioning) except the design: the design model carries the
    structure's pointing outputs ``[el, xel]`` (reduced to ``pointing.order`` with the
    deformation balanced too), the LQR scores the pointing error plus ``encoder_error_weight``
    times the encoder servo error with ``action_change_weight`` on the action change, and the
    reference's encoder angles are shifted so that the POINTING sits on the command: the
    model's deformation of the reference motion and the static deflection of the mean wind
    torque are taken out (:meth:`DesignMaps.reference_shift`).

    :param env: the environment (or its config / a :class:`ControlInterface`)
    :param name: label, default ``"LQG-pointing"``
    :param config: the shared LQG settings, default section ``lqg``
    :param pointing: the pointing settings, default section ``pointing`` of
        ``configs/controllers.yaml``
    """

    def __init__(self, env: Any = None, name: str = "LQG-pointing", config: LQGConfig | None = None,
                 pointing: PointingConfig | None = None) -> None:
        super().__init__(env, name, config, pointing or default_controllers_config().pointing)
