"""Model-predictive position controller (cvxpy + OSQP), condensed and parametrised once.

The MPC shares the LQG's design model, estimator, integrator, reference and weights
(:mod:`dss14_env.baselines.lqg`); it replaces the LQR law by a constrained finite-horizon problem.

Prediction (condensed: the commands are the only decision variables).  In deviation
coordinates about the reference the LQR state ``z = [x - x_ref; xi; r_prev - r_ss]`` obeys
``z_{j+1} = Az z_j + Bz (r_j - r_ss)`` exactly, so over the horizon ``N``::

    Z = Phi z_0 + Gamma (U - 1 (x) r_ss),        U = [r_0; ...; r_{N-1}]

Problem (decision ``U`` in units of the rate limit, slack ``s >= 0`` in units of the error
scale)::

    minimise    sum_j l(z_j, r_j - r_ss) + z_N' P z_N  +  lambda_1 sum(s) + lambda_2 |s|^2
    subject to  -r_max <= r_j <= r_max                                (rate, 0.25 deg/s)
                -a_max dt <= r_j - r_{j-1} <= a_max dt, r_{-1} = r_prev  (acceleration)
                -(e_max + s_j) <= e_j <= e_max + s_j,  j = 1..N        (soft servo-error bound)

``l`` is the LQR stage cost and ``P`` its Riccati solution, so with no constraint active the
first move equals the LQR's (tested).  The objective is written as ``quad_form(U, H) + q' U``
with ``H`` constant and ``q`` a :class:`cvxpy.Parameter`, the error bounds with a parameter
offset; the problem is DPP (:meth:`cvxpy.Problem.is_dpp`), stated and canonicalised by cvxpy
once and re-solved each step by :class:`dss14_env.baselines.qp.ParametricQP` (one OSQP
workspace whose ``q`` and ``u`` are updated, warm-started; ``Problem.solve`` when that fast
path cannot be built or a fast solve is not optimal).  The bounds are written as pairs of
linear inequalities, not as ``abs(.) <= b``: cvxpy would add an epigraph variable per bounded
entry (120 extra variables that appear in no cost), a degenerate QP on which OSQP's solution
polishing never succeeded and its duality-gap test needed thousands of iterations; as pairs the
QP has the 80 decision variables only and polishing succeeds.

The unconstrained shortcut.  With ``s = 0`` the objective is ``U' H U + q' U`` (``H`` positive
definite), minimised at ``U* = -H^{-1} q / 2``.  When ``U*`` meets every constraint (rate,
acceleration including the ``r_prev`` row, and the error bounds with ``s = 0``), ``(U*, 0)``
with all inequality multipliers zero except the slacks' ``s >= 0`` (multiplier ``lambda_1 >= 0``)
satisfies the KKT conditions of the convex QP: it IS the optimum, exactly, not an approximation.
So :class:`CondensedMPC` keeps ``-H^{-1} / 2`` (from a Cholesky factor, once); each step
:meth:`CondensedMPC.solve` computes ``U*`` and returns it (path ``"unconstrained"``) when it
meets the constraints with a relative margin of :data:`SHORTCUT_MARGIN`; otherwise it solves the
QP, its OSQP workspace warm-started from the previous step's solution when that step took the
shortcut (``U*``, zero slacks and duals: what OSQP would have started from had it solved that
step).

A solver exception, a status other than optimal on both paths, or a first move that violates
the hard limits makes the controller use the LQG action (clipped to the limits) for that step;
the fallbacks are recorded in ``info`` (each with its step and status) and never end the
episode.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import time
from dataclasses import dataclass
from typing import Any

import cvxpy as cp
import numpy as np
from scipy import linalg

from dss14_env.baselines.design import LQGConfig, MPCConfig, PointingConfig, default_controllers_config
from dss14_env.baselines.interface import LIMIT_MARGIN
from dss14_env.baselines.lqg import LQGController, LQGDesign
from dss14_env.baselines.qp import ParametricQP, set_values
from dss14_env.baselines.shaping import FEEDFORWARD_MARGIN

#: the path of a step whose unconstrained minimiser meets every constraint (no QP solved)
PATH_UNCONSTRAINED = "unconstrained"
#: the relative margin by which the unconstrained minimiser must meet each bound to be taken
#: (far above the rounding of its Cholesky solve, far below OSQP's tolerances)
SHORTCUT_MARGIN = 1e-9


@dataclass(frozen=True)
class MPCSettings:
    """Horizon, limits (SI), penalties and OSQP settings of the MPC problem.

    ``polishing``: OSQP's solution polishing (a solve of the KKT system on the active set the
    ADMM iterates identify; the documented way to a high-accuracy solution when that guess is
    right, and the ADMM solution otherwise).
    """

    horizon: int
    rate_limit: float
    rate_step: float           # a_max * dt, rad/s per step
    error_soft_limit: float    # rad
    slack_linear: float
    slack_quadratic: float
    eps_abs: float = 1e-5
    eps_rel: float = 1e-5
    max_iter: int = 4000
    polishing: bool = True

    def __post_init__(self) -> None:
        if int(self.horizon) != self.horizon or self.horizon < 2:
            raise ValueError(f"MPC horizon must be an integer >= 2, got {self.horizon!r}")
        for name in ("rate_limit", "rate_step", "error_soft_limit", "eps_abs", "eps_rel"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"MPC {name} must be positive and finite, got {v!r}")
        for name in ("slack_linear", "slack_quadratic"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"MPC {name} must be >= 0, got {getattr(self, name)!r}")
        if int(self.max_iter) != self.max_iter or self.max_iter < 1:
            raise ValueError(f"MPC max_iter must be a positive integer, got {self.max_iter!r}")

    def osqp_settings(self) -> dict[str, Any]:
        """The OSQP settings of both solve paths."""
        return {"eps_abs": self.eps_abs, "eps_rel": self.eps_rel, "max_iter": int(self.max_iter),
                "polishing": bool(self.polishing)}


@dataclass(frozen=True)
class MPCStep:
    """One solve of :meth:`CondensedMPC.solve`.

    :param r: first move (rad/s), None when the solve failed or the move violates the limits
    :param status: cvxpy status (or ``"limits_violated"``, ``"solver_error: ..."``)
    :param time_s: wall time of the solve, s
    :param path: ``"unconstrained"`` (no active constraint, :data:`PATH_UNCONSTRAINED`),
        ``"osqp"`` (fast path) or ``"cvxpy"`` (``Problem.solve``)
    :param fast_status: the fast path's status when it was re-solved through cvxpy, else None
    """

    r: np.ndarray | None
    status: str
    time_s: float
    path: str
    fast_status: str | None = None


class CondensedMPC:
    """The parametrised MPC problem, built once (see the module docstring).

    :param design: the LQG design whose model, weights and Riccati solution are used
    :param settings: horizon, limits, penalties and OSQP settings
    :param fast: use the OSQP fast path (default True; False: ``Problem.solve`` every step)
    :param shortcut: take the unconstrained minimiser when it meets the constraints (default
        True; False: a QP every step)
    """

    def __init__(self, design: LQGDesign, settings: MPCSettings, fast: bool = True,
                 shortcut: bool = True) -> None:
        self.design = design
        self.settings = st = settings
        N = int(st.horizon)
        nz, m = design.Az.shape[0], design.Bz.shape[1]
        self.N, self.nz, self.m = N, nz, m
        H = self._prediction(design)
        # scaling: u = rate_limit * U, e and s in error_scale
        ru, es = st.rate_limit, design.weights.error_scale
        self._ru, self._es = ru, es
        Hs = H * ru * ru
        self._Hs_scale = float(np.max(np.abs(Hs)))
        Hs = Hs / self._Hs_scale
        Hs = 0.5 * (Hs + Hs.T)
        lam_min = np.linalg.eigvalsh(Hs).min()
        if lam_min <= 0:
            raise ValueError(f"MPC Hessian not positive definite (min eigenvalue {lam_min:.3g})")
        self.H_scaled = Hs
        self.shortcut = bool(shortcut)
        # U* = -H^{-1} q / 2: -H^{-1}/2 once, from the Cholesky factor (H is checked definite)
        self._U_of_q = -0.5 * linalg.cho_solve(linalg.cho_factor(Hs), np.eye(N * m))
        self._warm: np.ndarray | None = None  # the last shortcut's U*, until the next QP solve
        self._parameter_maps()
        # ---- cvxpy problem (DPP)
        self.U = cp.Variable(N * m, name="U")
        self.s = cp.Variable(N * m, nonneg=True, name="slack")
        self.q = cp.Parameter(N * m, name="q")               # linear cost term (scaled)
        self.e0 = cp.Parameter(N * m, name="e_free")         # predicted errors at U = 0 (scaled)
        self.u_prev = cp.Parameter(m, name="r_prev")         # previous applied command (scaled)
        Eg = self.Egam * ru / es
        step = st.rate_step / ru
        lim_e = st.error_soft_limit / es
        # the slack penalty is weighed against the LQR cost per step: 1 (e/sigma_e)^2 ~ cost 1
        w1 = st.slack_linear / self._Hs_scale
        w2 = st.slack_quadratic / self._Hs_scale
        e_pred = self.e0 + Eg @ self.U
        D = np.eye(N * m) - np.eye(N * m, k=-m)  # U_j - U_{j-1}
        dU = D @ self.U - cp.hstack([self.u_prev, np.zeros((N - 1) * m)])
        cons = [self.U <= 1.0, -self.U <= 1.0, dU <= step, -dU <= step,
                e_pred <= lim_e + self.s, -e_pred <= lim_e + self.s]
        obj = cp.quad_form(self.U, cp.psd_wrap(Hs)) + self.q @ self.U + w1 * cp.sum(self.s) \
            + w2 * cp.sum_squares(self.s)
        self.problem = cp.Problem(cp.Minimize(obj), cons)
        if not self.problem.is_dpp():
            raise RuntimeError("the MPC problem is not DPP: it would be re-canonicalised every "
                               "step")
        # the problem is these numbers' (the canonical data of an equal problem is reused)
        digest = hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in (Hs, Eg))).hexdigest()
        key = ("CondensedMPC", N, m, Hs.shape, Eg.shape, step, lim_e, w1, w2, digest)
        self.qp = ParametricQP(self.problem, [self.q, self.e0, self.u_prev], self.U,
                               st.osqp_settings(), fast=fast, key=key)
        # the constraint rows of U, stacked: U (rate), D U (rate change), Eg U (errors), and
        # their bounds; the shortcut checks |C U - c0| <= bound in one product
        self._C = np.vstack([np.eye(N * m), D, Eg])
        self._C_bound = (1.0 - SHORTCUT_MARGIN) * np.concatenate([np.ones(N * m), np.full(N * m, step),
                                                                  np.full(N * m, lim_e)])
        self._c0 = np.zeros(3 * N * m)

    def _prediction(self, design: LQGDesign) -> np.ndarray:
        """Prediction matrices of a design; returns the (unscaled) Hessian ``H``."""
        N, nz, m = self.N, design.Az.shape[0], design.Bz.shape[1]
        if nz != self.nz:
            raise ValueError(f"design has {nz} LQR states, the MPC was built for {self.nz}")
        Az, Bz, n = design.Az, design.Bz, design.dm.n
        # z_j = Phi_j z0 + sum_i Gam_{j,i} u_i   (j = 0..N)
        Phi = np.zeros(((N + 1) * nz, nz))
        Gam = np.zeros(((N + 1) * nz, N * m))
        Phi[:nz] = np.eye(nz)
        for j in range(1, N + 1):
            Phi[j * nz:(j + 1) * nz] = Az @ Phi[(j - 1) * nz:j * nz]
            Gam[j * nz:(j + 1) * nz] = Az @ Gam[(j - 1) * nz:j * nz]
            Gam[j * nz:(j + 1) * nz, (j - 1) * m:j * m] = Bz
        # cost: sum_j [z_j; u_j]' [[Q, S], [S', R]] [z_j; u_j] + z_N' P z_N
        Q, R, S, P = design.Qz, design.Rz, design.Sz, design.P_lqr
        Qbar = linalg.block_diag(*([Q] * N + [P]))
        Rbar = linalg.block_diag(*([R] * N))
        Sbar = np.zeros(((N + 1) * nz, N * m))
        for j in range(N):
            Sbar[j * nz:(j + 1) * nz, j * m:(j + 1) * m] = S
        H = Gam.T @ Qbar @ Gam + Rbar + Gam.T @ Sbar + Sbar.T @ Gam
        # errors e_j = -Cz x_j (deviation coordinates), j = 1..N: the servo error (-theta) of an
        # encoder design, the pointing error of a pointing design
        Ce = np.zeros((2, nz))
        Ce[:, :n] = -design.dm.Cz
        E = np.kron(np.eye(N + 1), Ce)[2:]
        self.design = design
        self.Phi, self.Gam = Phi, Gam
        self.F = Gam.T @ Qbar @ Phi + Sbar.T @ Phi  # linear term: 2 (F z0)' u
        self.Ephi, self.Egam = E @ Phi, E @ Gam
        self.H = 0.5 * (H + H.T)
        return self.H

    def _parameter_maps(self) -> None:
        """The parameters as affine maps of ``(z0, r_ss)`` for the current design (scaled):
        ``q = Qz z0 + Qr r_ss``, ``e0 = Ez z0 + Er r_ss`` (:meth:`set_parameters`).
        """
        ru, es, N, m = self._ru, self._es, self.N, self.m
        T = np.kron(np.ones((N, 1)), np.eye(m))  # the ramp's steady commands over the horizon
        # cost in u~ = U ru - T r_ss: u~' H u~ + 2 (F z0)' u~  ->  in U (scaled, up to a constant)
        k = 2.0 * ru / self._Hs_scale
        H = self.H_scaled * self._Hs_scale / (ru * ru)
        self._Qz, self._Qr = k * self.F, -k * (H @ T)
        self._Ez, self._Er = self.Ephi / es, -(self.Egam @ T) / es

    def load_design(self, design: LQGDesign) -> None:
        """Switch to another design with the same controllable part (e.g. another wind model).

        Only the free response changes; the Hessian, and so the cvxpy problem, must not.

        :raises ValueError: if the new design's Hessian differs from the one the problem was
            built with
        """
        if design is self.design:
            return
        H_old = self.H
        H = self._prediction(design)
        if np.max(np.abs(H - H_old)) > 1e-8 * np.max(np.abs(H_old)):
            raise ValueError("the new design changes the MPC Hessian; build a new CondensedMPC")
        self._parameter_maps()

    def parameters(self, z0: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The state-dependent parameters of one step, scaled: ``(q, e_free, r_prev)``.

        :param z0: LQR state ``[x - x_ref; xi; r_prev - r_ss]`` (SI)
        :param r_ss: steady command of the ramp (rad/s), shape (2,)
        :param r_prev: previous applied command (rad/s), shape (2,)
        """
        return (self._Qz @ z0 + self._Qr @ r_ss, self._Ez @ z0 + self._Er @ r_ss,
                np.clip(r_prev / self._ru, -1.0, 1.0))

    def set_parameters(self, z0: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> None:
        """Load the parameters of one step (:meth:`parameters`) into the cvxpy problem."""
        set_values([self.q, self.e0, self.u_prev], list(self.parameters(z0, r_ss, r_prev)))

    def unconstrained(self, q: np.ndarray, e_free: np.ndarray, u_prev: np.ndarray) -> np.ndarray | None:
        """The minimiser ``U* = -H^{-1} q / 2`` of the parameters ``(q, e_free, u_prev)``
        (:meth:`parameters`) when it meets every constraint with the slacks at zero (each bound
        by the relative margin :data:`SHORTCUT_MARGIN`), else None; when it does, it is the
        QP's solution (module docstring).
        """
        U = self._U_of_q @ q
        n, m = self.N * self.m, self.m
        c0 = self._c0
        c0[n:n + m] = u_prev
        c0[2 * n:] = -e_free
        rows = self._C @ U - c0
        if not np.all(np.abs(rows) <= self._C_bound):
            return None
        return U

    def solve_qp(self) -> tuple[np.ndarray | None, str, str, str | None]:
        """Solve the QP at the loaded parameters' values (:class:`ParametricQP`), warm-started
        from the last shortcut's solution when the previous step took it.

        :return: ``(U or None, status, path, fast status)``; a solver exception gives None and
            the status ``"solver_error: <type>: <message>"``
        """
        try:
            if self._warm is not None:
                self.qp.warm_start(self._warm)
            res = self.qp.solve()
            return res.x, res.status, res.path, res.fast_status
        except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
            return None, f"solver_error: {type(exc).__name__}: {exc}", "", None
        finally:
            self._warm = None

    def solve(self, z0: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> MPCStep:
        """Solve one step for one row (``z0`` ``(n_z,)``, ``r_ss`` and ``r_prev`` ``(2,)``):
        the unconstrained minimiser when it meets the constraints, else the QP.

        :return: the :class:`MPCStep`; its ``r`` (rad/s) is None when the solve failed or the
            first move violates the hard limits
        """
        values = self.parameters(z0, r_ss, r_prev)
        t0 = time.perf_counter()
        U = self.unconstrained(*values) if self.shortcut else None
        if U is not None:  # inside every bound: no clip or limit check to do
            self._warm = U
            return MPCStep(U[:self.m] * self._ru, cp.OPTIMAL, time.perf_counter() - t0, PATH_UNCONSTRAINED)
        set_values([self.q, self.e0, self.u_prev], list(values))
        U, status, path, fast_status = self.solve_qp()
        dt = time.perf_counter() - t0
        if status != cp.OPTIMAL or U is None:
            return MPCStep(None, status, dt, path, fast_status)
        u0 = np.asarray(U[:self.m], float)
        step = self.settings.rate_step / self._ru
        up = self.u_prev.value
        # OSQP meets constraints to ~eps_abs; more than 1 % of a rate step is a failed solve
        viol = max(float(np.max(np.abs(u0) - 1.0)), float(np.max(np.abs(u0 - up) - step)))
        if viol > 0.01 * step:
            return MPCStep(None, "limits_violated", dt, path, fast_status)
        u0 = np.clip(np.clip(u0, up - step, up + step), -1.0, 1.0)
        return MPCStep(u0 * self._ru, status, dt, path, fast_status)


class MPCController(LQGController):
    """The MPC behind the controller interface: the LQG's estimator, wind inference, reference
    and integrator, with the constrained problem as the law and the LQG law as the fallback.

    Not batchable (``batchable = False``): one problem per episode and step; run one instance
    per episode.  ``info`` carries ``mpc_solve_time_s`` (the solve), ``status`` and ``qp_path``
    of the step, and the episode's ``n_solves``, ``qp_paths`` (path -> steps: ``unconstrained``,
    ``osqp``, ``cvxpy``; :class:`MPCStep`), ``n_fallbacks``, ``fallbacks`` (a list of
    ``{"step": k, "status": s}``, see :mod:`dss14_env.baselines.base`), ``fallback_statuses``
    (status -> count) and ``resolves`` (steps whose fast solve was not optimal and was re-solved
    through ``Problem.solve``, as ``{"step": k, "status": fast status}``).

    :param env: the environment (or its config / a
        :class:`~dss14_env.baselines.interface.ControlInterface`)
    :param name: label, default ``"MPC"``
    :param config: MPC settings, default section ``mpc`` of ``configs/controllers.yaml``
    :param lqg_config: settings of the shared estimator/fallback, default section ``lqg``
    :param fast: use the OSQP fast path of :class:`~dss14_env.baselines.qp.ParametricQP`
        (default True)
    :param shortcut: take the unconstrained minimiser when it meets the constraints
        (:class:`CondensedMPC`, default True)
    :param pointing: None (the encoder design) or the pointing design's settings (section
        ``pointing``: :class:`PointingMPCController`); its ``mpc_action_change_weight`` is the
        MPC's action-change multiplier
    :param pointing_noise: with ``pointing``, the estimator also measures the pointing (the
        monopulse sensor, :class:`dss14_env.baselines.monopulse.MonopulseMPCController`)
    """

    batchable = False

    def __init__(self, env: Any = None, name: str = "MPC", config: MPCConfig | None = None,
                 lqg_config: LQGConfig | None = None, fast: bool = True,
                 pointing: PointingConfig | None = None, *, pointing_noise: float | None = None,
                 shortcut: bool = True) -> None:
        cc = default_controllers_config()
        self.mpc_config = mcfg = config or cc.mpc
        lcfg = lqg_config or cc.lqg
        # the constraints keep the MPC within the limits: its reference keeps the default share
        lcfg = dataclasses.replace(lcfg, shaper=mcfg.shaper, action_change_weight=mcfg.action_change_weight,
                                   reference_accel_share=FEEDFORWARD_MARGIN)
        if pointing is not None:
            pointing = dataclasses.replace(pointing, action_change_weight=pointing.mpc_action_change_weight)
        self.fast, self.shortcut = bool(fast), bool(shortcut)
        self._mpcs: dict[int, CondensedMPC] = {}
        super().__init__(env, name, lcfg, pointing, pointing_noise=pointing_noise)
        ci = self.interface
        self.settings = MPCSettings(int(mcfg.horizon), ci.rate_limit * (1 - LIMIT_MARGIN),
                                    ci.rate_step * (1 - LIMIT_MARGIN),
                                    mcfg.error_soft_limit, mcfg.slack_weight_linear,
                                    mcfg.slack_weight_quadratic, mcfg.eps_abs, mcfg.eps_rel,
                                    int(mcfg.max_iter))

    def problem_for(self, design: LQGDesign) -> CondensedMPC:
        """The MPC problem of a design: built once per LQR state size (the direction-free and
        the inferred gust models differ in filter states) and re-pointed otherwise.
        """
        nz = design.n_z
        if nz not in self._mpcs:
            self._mpcs[nz] = CondensedMPC(design, self.settings, fast=self.fast, shortcut=self.shortcut)
        else:
            self._mpcs[nz].load_design(design)
        return self._mpcs[nz]

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self.n_solves = 0
        self.qp_paths: dict[str, int] = {}
        self.fallbacks: list[dict[str, Any]] = []
        self.resolves: list[dict[str, Any]] = []
        self._last = MPCStep(None, "", 0.0, "")

    def fallback(self, design: LQGDesign, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> np.ndarray:
        """The LQG command, clipped to the rate and rate-change limits."""
        r = self.lqr_command(design, z, r_ss)
        st = self.settings
        return np.clip(np.clip(r, r_prev - st.rate_step, r_prev + st.rate_step),
                       -st.rate_limit, st.rate_limit)

    def law_rows(self, design: LQGDesign, rows: np.ndarray, z: np.ndarray, r_ss: np.ndarray,
                 r_prev: np.ndarray) -> np.ndarray:
        """The MPC's first move for the episode's row (one row: the MPC is not batchable)."""
        mpc = self.problem_for(design)
        step = int(self._k[rows[0]])
        res = self._last = mpc.solve(z[0], r_ss[0], r_prev[0])
        self.n_solves += 1
        self.qp_paths[res.path] = self.qp_paths.get(res.path, 0) + 1
        if res.fast_status is not None:
            self.resolves.append({"step": step, "status": res.fast_status})
        if res.r is None:
            self.fallbacks.append({"step": step, "status": res.status})
            return self.fallback(design, z, r_ss, r_prev)
        return res.r[None]

    def episode_info(self) -> dict[str, Any]:
        statuses: dict[str, int] = {}
        for f in self.fallbacks:
            key = f["status"].split(":")[0]
            statuses[key] = statuses.get(key, 0) + 1
        return {**super().episode_info(), "mpc_solve_time_s": self._last.time_s,
                "status": self._last.status, "qp_path": self._last.path, "n_solves": self.n_solves,
                "qp_paths": dict(self.qp_paths),
                "n_fallbacks": len(self.fallbacks), "fallbacks": [dict(f) for f in self.fallbacks],
                "fallback_statuses": statuses, "resolves": [dict(r) for r in self.resolves]}


class PointingMPCController(MPCController):
    """The MPC on the dish's pointing outputs (``mpc_pointing``): the pointing LQG's design model,
    estimator, reference shift and cost (:class:`dss14_env.baselines.lqg.PointingLQGController`)
    with the constrained problem as the law; its soft error bound is on the predicted POINTING
    error, its action-change multiplier ``pointing.mpc_action_change_weight``.

    :param env: the environment (or its config / a
        :class:`~dss14_env.baselines.interface.ControlInterface`)
    :param name: label, default ``"MPC-pointing"``
    :param config: MPC settings, default section ``mpc``
    :param lqg_config: the shared estimator settings, default section ``lqg``
    :param fast: use the OSQP fast path (default True)
    :param pointing: the pointing settings, default section ``pointing``
    :param shortcut: take the unconstrained minimiser when it meets the constraints (default True)
    """

    def __init__(self, env: Any = None, name: str = "MPC-pointing", config: MPCConfig | None = None,
                 lqg_config: LQGConfig | None = None, fast: bool = True,
                 pointing: PointingConfig | None = None, *, shortcut: bool = True) -> None:
        super().__init__(env, name, config, lqg_config, fast,
                         pointing or default_controllers_config().pointing, shortcut=shortcut)
