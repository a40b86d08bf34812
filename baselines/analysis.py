"""Closed-loop analysis of the controllers on linear plant models (no simulation).

* :func:`dare_residual`: relative residual of a discrete algebraic Riccati equation;
* :func:`lqg_as_linear`: an LQG design (hold, no clipping) as one LTI controller
  :class:`LinearController` (:func:`pi_as_linear`: the sampled PI); :func:`closed_loop`
  interconnects such a controller with a (full-order) plant model into a :class:`ClosedLoop`;
  :func:`stationary_performance` gives its exact stationary 3-sigma servo error and expected
  per-step cost from a discrete Lyapunov equation, ``X = A X A' + W``;
* :func:`riccati_cost`: the same expected cost of an LQG on its own model from its two Riccati
  solutions alone (the check of the yardstick's figure);
* :func:`sampled_loop`, :func:`sampled_three_sigma_mdeg`: the sampled PI of
  :class:`dss14_env.baselines.pi.PIController` on the environment's discretised plant in wind,
  the counterpart of :func:`dss14_env.wind.loads.three_sigma_mdeg` for the continuous PI loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from dss14_env.baselines.design import DesignModel
from dss14_env.baselines.interface import Weights
from dss14_env.baselines.pi import gains_per_axis
from dss14_env.core.units import R2MD
from dss14_env.model.linsys import stationary_covariance

if TYPE_CHECKING:  # the design type only; lqg.py imports this module
    from dss14_env.baselines.lqg import LQGDesign


# ------------------------------------------------------------------------- Riccati equations
def dare_residual(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, P: np.ndarray,
                  S: np.ndarray | None = None) -> float:
    """Relative residual of ``P = A'PA - (A'PB + S)(R + B'PB)^-1 (B'PA + S') + Q``.

    :return: ``||residual||_F / max(||P||_F, ||Q||_F)``
    """
    S = np.zeros((A.shape[0], B.shape[1])) if S is None else S
    G = A.T @ P @ B + S
    res = A.T @ P @ A - P - G @ np.linalg.solve(R + B.T @ P @ B, G.T) + Q
    return float(np.linalg.norm(res) / max(np.linalg.norm(P), np.linalg.norm(Q)))


def riccati_cost(design: LQGDesign) -> float:
    """Expected per-step cost of an LQG design on its own model, from the Riccati solutions.

    ``J = tr(P_c W) + tr(Sigma K' (R + B' P_c B) K)``: the full-information cost plus the
    cost of the estimation error, with ``P_c`` the LQR solution, ``W`` the process-noise
    covariance of the augmented state and ``Sigma`` the filtered (a-posteriori) error
    covariance of the Kalman filter.
    """
    if design.n_d:
        raise ValueError("riccati_cost is for designs without disturbance states")
    n = design.dm.n
    nz = design.n_z
    W = np.zeros((nz, nz))
    W[:n, :n] = design.Qn
    Ce = design.dm.C
    P = design.P_kf
    Sigma = P - P @ Ce.T @ np.linalg.solve(Ce @ P @ Ce.T + design.dm.R, Ce @ P)
    Kx = design.K[:, :n]
    Bz, Pc, Rz = design.Bz, design.P_lqr, design.Rz
    return float(np.trace(Pc @ W) + np.trace(Sigma @ Kx.T @ (Rz + Bz.T @ Pc @ Bz) @ Kx))


# ------------------------------------------------------------------------- LQG closed loops
@dataclass(frozen=True)
class LinearController:
    """A discrete LTI controller ``zeta+ = Ac zeta + Bc y``, ``r = Cc zeta + Dc y`` (regulation
    about a constant command; ``y`` the measured encoder angles, rad; ``r`` rad/s).
    """

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
    Ce = dm.estimator_output(nd) if design.Ce is None else design.Ce
    Imlc = np.eye(ne) - Lg @ Ce  # [x; d]_k|k = (I - L C) [x; d]^- + L y
    Ci = Ce[2:4] if design.integral_output == "pointing" else Ce[:2]  # what the integrator sums
    # r = Fx [x; d]_k|k - Ki xi - Ku r_prev
    Fx = np.hstack([-Kx, -(np.eye(2) + Ku) if nd else np.zeros((2, 0))])
    Cc = np.hstack([Fx @ Imlc, -Ki, -Ku])
    Dc = Fx @ Lg
    nzc = ne + ni + 2
    Ac = np.zeros((nzc, nzc))
    Bc = np.zeros((nzc, Ce.shape[0]))
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
        Ac[ne:ne + ni, :ne] = -dm.dt * Ci @ Imlc
        Ac[ne:ne + ni, ne:ne + ni] = np.eye(ni)
        Bc[ne:ne + ni] = -dm.dt * Ci @ Lg
    Ac[ne + ni:] = Cc
    Bc[ne + ni:] = Dc
    return LinearController(Ac, Bc, Cc, Dc)


def pi_as_linear(dt: float, gains: str | tuple = "kp1", model: Any = None) -> LinearController:
    """The sampled PI of :class:`dss14_env.baselines.pi.PIController` (hold, no clipping) as one
    LTI system from ``y`` to ``r``: ``e = -y``, ``I_k = I_{k-1} + dt (e_k + e_{k-1}) / 2``,
    ``r_k = kp e_k + ki I_k``; controller state ``[I_{k-1}; e_{k-1}]``.

    :param dt: control period, s
    :param gains: gain-set name of ``model`` (None: the shipped one) or ``(kp, ki)``
    """
    kp, ki = gains_per_axis(gains, model)
    h, eye, zero = 0.5 * dt, np.eye(2), np.zeros((2, 2))
    Ac = np.block([[eye, h * eye], [zero, zero]])
    Bc = np.vstack([-h * eye, -eye])
    Cc = np.hstack([np.diag(ki), h * np.diag(ki)])
    Dc = -np.diag(kp + h * ki)
    return LinearController(Ac, Bc, Cc, Dc)


@dataclass(frozen=True)
class ClosedLoop:
    """Plant (discrete design model) + linear controller, driven by the plant's process noise
    and the measurement noise.  State ``[x_plant; zeta; r_prev]``.
    """

    A: np.ndarray
    W: np.ndarray          # covariance of the state noise per step
    C_e: np.ndarray        # servo error e = -theta (hold)
    C_r: np.ndarray        # rate command r_k = C_r X + D_rv v_k
    D_rv: np.ndarray
    C_rprev: np.ndarray
    R: np.ndarray
    C_p: np.ndarray | None = None  # pointing error [el, xel] = -Cp x (hold), when the plant has it

    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.A)

    def spectral_radius(self) -> float:
        return float(np.max(np.abs(self.eigenvalues())))


def closed_loop(plant: DesignModel, ctrl: LinearController,
                measurement: tuple[np.ndarray, np.ndarray] | None = None) -> ClosedLoop:
    """Interconnect a plant model with a linear controller (``y = C x + v``).

    The controller's command enters the plant as the held input of the next period; the
    previous command is carried as two extra states so the action change is an output.

    :param measurement: ``(C, R)``: what the controller measures and the noise covariance, when
        not the plant's encoders ``(plant.C, plant.R)`` (e.g. the encoders and the monopulse
        sensor, :func:`design_measurement`)
    """
    n, nc = plant.n, ctrl.Ac.shape[0]
    Ap, Bp = plant.Ad, plant.Bd
    Cp, Rm = (plant.C, plant.R) if measurement is None else measurement
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
    W = Wx + Bv @ Rm @ Bv.T
    C_e = np.zeros((2, N))
    C_e[:, :n] = -plant.C
    C_r = np.zeros((2, N))
    C_r[:, :n] = ctrl.Dc @ Cp
    C_r[:, n:n + nc] = ctrl.Cc
    C_rprev = np.zeros((2, N))
    C_rprev[:, n + nc:] = np.eye(2)
    C_p = None
    if plant.Cp is not None:
        C_p = np.zeros((2, N))
        C_p[:, :n] = -plant.Cp
    return ClosedLoop(A, W, C_e, C_r, ctrl.Dc, C_rprev, Rm, C_p)


def design_measurement(design: LQGDesign) -> tuple[np.ndarray, np.ndarray] | None:
    """``(C, R)`` of a design's measurement on its model's state (the estimator's without the
    disturbance columns) for :func:`closed_loop`; None for the encoders alone.
    """
    if design.Ce is None or design.Ce.shape[0] == 2:
        return None
    return design.Ce[:, :design.dm.n], design.Rm


def stationary_performance(cl: ClosedLoop, weights: Weights) -> dict[str, Any]:
    """Stationary servo-error statistics and expected per-step cost of a closed loop.

    Solves ``X = A X A' + W`` (:func:`dss14_env.model.linsys.stationary_covariance`).

    :return: dict with ``three_sigma_mdeg`` ([az, el]), ``rms_mdeg``, ``rate_rms`` (rad/s),
        ``command_change_rms_rad_s`` (rms of the rate command's change per period, per axis),
        ``cost`` (expected ``|e/sigma_e|^2 + w |da|^2`` per step, ``e`` the servo error),
        ``cost_error``, ``cost_action`` and ``spectral_radius``; with a plant that has pointing
        outputs also ``pointing_three_sigma_mdeg`` and ``pointing_rms_mdeg`` ([el, xel]) and
        ``cost_pointing`` (the cost with the pointing error in place of the servo error)
    :raises ValueError: if the loop is not asymptotically stable
    """
    rho = cl.spectral_radius()
    if rho >= 1.0:
        raise ValueError(f"closed loop unstable (spectral radius {rho:.6f}): no stationary error")
    X = stationary_covariance(cl.A, cl.W)
    var_e = np.diag(cl.C_e @ X @ cl.C_e.T)
    Cd = cl.C_r - cl.C_rprev
    var_da = np.diag(Cd @ X @ Cd.T + cl.D_rv @ cl.R @ cl.D_rv.T) / weights.action_scale ** 2
    var_r = np.diag(cl.C_r @ X @ cl.C_r.T + cl.D_rv @ cl.R @ cl.D_rv.T)
    ce = float(var_e.sum() / weights.error_scale ** 2)
    ca = float(weights.action_change * var_da.sum())
    sig = np.sqrt(var_e) * R2MD
    dt_acc = np.sqrt(var_da) * weights.action_scale
    out = {"three_sigma_mdeg": (3 * sig).tolist(), "rms_mdeg": sig.tolist(),
           "rate_rms_rad_s": np.sqrt(var_r).tolist(), "cost": ce + ca, "cost_error": ce,
           "cost_action": ca, "spectral_radius": rho}
    if cl.C_p is not None:
        var_p = np.diag(cl.C_p @ X @ cl.C_p.T)
        sp = np.sqrt(var_p) * R2MD
        out.update({"pointing_three_sigma_mdeg": (3 * sp).tolist(), "pointing_rms_mdeg": sp.tolist(),
                    "cost_pointing": float(var_p.sum() / weights.error_scale ** 2) + ca})
    out["command_change_rms_rad_s"] = dt_acc.tolist()
    return out


# ------------------------------------------------------------------------- the sampled PI
def sampled_loop(plant: Any, kappa: np.ndarray, kp: np.ndarray, ki: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sampled PI loop of :class:`dss14_env.baselines.pi.PIController` on a discretised plant
    (hold, linear).

    No quantisation, no limiter, command fixed: ``e[k] = -theta[k]``.  State
    ``s[k] = [x[k], I[k-1], e[k-1]]``; ``s[k+1] = Phi s[k] + W xi[k]``.

    :param plant: a :class:`dss14_env.envs.plant.Plant`
    :param kappa: wind-direction factors (:meth:`dss14_env.envs.plant.Plant.kappa`)
    :param kp: proportional gains ``[az, el]``, 1/s
    :param ki: integral gains ``[az, el]``, 1/s^2
    :return: ``(Phi, W, C_e)`` with ``e[k] = C_e s[k]``
    """
    n, dt = plant.n, plant.dt
    Ce = -plant.C[:2]
    Kp, Ki = np.diag(kp), np.diag(ki)
    B = plant.Bd_r
    Phi = np.zeros((n + 4, n + 4))
    Phi[:n, :n] = plant.Ad + B @ (Kp + 0.5 * dt * Ki) @ Ce
    Phi[:n, n:n + 2] = B @ Ki
    Phi[:n, n + 2:] = 0.5 * dt * B @ Ki
    Phi[n:n + 2, :n] = 0.5 * dt * Ce
    Phi[n:n + 2, n:n + 2] = np.eye(2)
    Phi[n:n + 2, n + 2:] = 0.5 * dt * np.eye(2)
    Phi[n + 2:, :n] = Ce
    W = np.zeros((n + 4, plant.noise_rank))
    W[:n] = plant.noise_matrix(np.asarray(kappa, float))
    return Phi, W, np.hstack([Ce, np.zeros((2, 4))])


def sampled_three_sigma_mdeg(plant: Any, direction: float, gains: str | tuple = "kp1") -> np.ndarray:
    """Exact stationary 3-sigma servo errors ``[az, el]`` (mdeg) of the sampled PI in wind.

    Solves ``S = Phi S Phi^T + W W^T`` for :func:`sampled_loop`; the mean wind torque only
    shifts the mean, which the integral action removes.

    :param plant: a :class:`dss14_env.envs.plant.Plant` (its ``dt`` and wind speed)
    :param direction: wind direction relative to the dish, rad
    :param gains: gain-set name or ``(kp, ki)``
    :raises ValueError: if the sampled loop is unstable
    """
    kp, ki = gains_per_axis(gains)
    Phi, W, Ce = sampled_loop(plant, plant.kappa(direction), kp, ki)
    rho = float(np.max(np.abs(np.linalg.eigvals(Phi))))
    if rho >= 1.0:
        raise ValueError(f"the sampled PI loop is unstable (spectral radius {rho:.6f})")
    S = stationary_covariance(Phi, W @ W.T)
    return 3.0 * np.sqrt(np.diag(Ce @ S @ Ce.T)) * R2MD
