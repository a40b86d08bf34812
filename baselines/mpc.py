"""Model-predictive position controller (cvxpy + OSQP), condensed and parametrised once.

The MPC shares the LQG's design model, estimator, integrator and weights
(:mod:`dss14_env.baselines.lqg`); it replaces the LQR law by a constrained finite-horizon problem.

Prediction (condensed: the commands are the only decision variables).  In deviation
coordinates about the commanded ramp ``c + c_rate t`` the LQR state ``z = [x - x_ref; xi;
r_prev - r_ss]`` obeys ``z_{j+1} = Az z_j + Bz (r_j - r_ss)`` exactly, so over the horizon ``N``::

    Z = Phi z_0 + Gamma (U - 1 (x) r_ss),        U = [r_0; ...; r_{N-1}]

Problem (decision ``U`` in units of the rate limit, slack ``s >= 0`` in units of the error
scale)::

    minimise    sum_j l(z_j, r_j - r_ss) + z_N' P z_N  +  lambda_1 sum(s) + lambda_2 |s|^2
    subject to  |r_j| <= r_max                                   (rate, 0.25 deg/s)
                |r_0 - r_prev| <= a_max dt,  |r_j - r_{j-1}| <= a_max dt      (acceleration)
                |e_j| <= e_max + s_j,  j = 1..N                   (soft servo-error bound)

``l`` is the LQR stage cost and ``P`` its Riccati solution, so with no constraint active the
first move equals the LQR's (tested).  The objective is written as ``quad_form(U, H) + q' U``
with ``H`` constant and ``q`` a :class:`cvxpy.Parameter`, the error bounds with a parameter
offset; the problem is DPP (:meth:`cvxpy.Problem.is_dpp`) and canonicalised by cvxpy once
(:class:`CanonicalQP`): its OSQP data ``(P, q, A, l, u)`` is affine in the parameters with
``P`` and ``A`` constant, so each step only updates ``q`` and ``u`` of one OSQP workspace and
re-solves it warm-started.  (Calling ``Problem.solve`` every step re-applies the parameters
through cvxpy's sparse tensors; with cvxpy 1.9 / scipy 1.17 that alone costs 2-4 ms a step.
Both paths give the same solution, tested.)  A solver exception, a status other than optimal,
or a first
move that violates the hard limits makes the controller use the LQG action (clipped to the
limits) for that step; the fallbacks are counted in ``info`` and never end the episode.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.sparse as sp
from scipy import linalg

from dss14_env.baselines.design import LQGConfig, MPCConfig, default_controllers_config
from dss14_env.baselines.lqg import LQGController, LQGDesign


@dataclass(frozen=True)
class MPCSettings:
    """Horizon, limits (SI) and penalties of the MPC problem."""

    horizon: int
    rate_limit: float
    rate_step: float           # a_max * dt, rad/s per step
    error_soft_limit: float    # rad
    slack_linear: float
    slack_quadratic: float
    eps_abs: float = 1e-5
    eps_rel: float = 1e-5
    max_iter: int = 4000

    def __post_init__(self) -> None:
        if int(self.horizon) != self.horizon or self.horizon < 2:
            raise ValueError(f"MPC horizon must be an integer >= 2, got {self.horizon!r}")
        for name in ("rate_limit", "rate_step", "error_soft_limit"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"MPC {name} must be positive and finite, got {v!r}")
        for name in ("slack_linear", "slack_quadratic"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"MPC {name} must be >= 0, got {getattr(self, name)!r}")


class CanonicalQP:
    """A DPP cvxpy problem, canonicalised once for OSQP, re-solved with new parameter values.

    At construction every parameter entry is probed (cvxpy's own ``get_problem_data`` with a
    unit value, the others zero) to get the affine maps ``q = q0 + Mq p``, ``u = u0 + Mu p``;
    a random parameter vector then checks that ``P`` and ``A`` stay constant and the maps are
    exact (``l`` is -inf: cvxpy's OSQP data has inequalities only here), else
    :class:`ValueError`.  One OSQP workspace is set up; :meth:`solve`
    updates ``q``, ``u`` and solves, warm-started from the previous solution (OSQP's default).

    :param problem: DPP problem whose parameters enter only the linear cost and the upper
        bounds of inequalities (as in :class:`CondensedMPC`)
    :param params: its parameters, in the order of the vector :meth:`solve` reads
    :param variable: the variable to return
    :param solver_opts: OSQP settings (``eps_abs``, ``eps_rel``, ``max_iter``, ``polishing``)
    """

    def __init__(self, problem: cp.Problem, params: list[cp.Parameter], variable: cp.Variable,
                 solver_opts: dict[str, Any]) -> None:
        import osqp
        from cvxpy.reductions.solvers.qp_solvers.osqp_qpif import OSQP as CvxpyOSQP

        self.params = list(params)
        saved = [None if p.value is None else np.array(p.value, copy=True) for p in self.params]
        sizes = [int(p.size) for p in self.params]
        n_p = sum(sizes)

        def data_at(vec: np.ndarray) -> tuple[Any, np.ndarray, Any, np.ndarray, int]:
            k = 0
            for p, n in zip(self.params, sizes):
                p.value = vec[k:k + n].reshape(p.shape)
                k += n
            d, _, _ = problem.get_problem_data(cp.OSQP)
            if d[cp.settings.A].shape[0]:
                raise ValueError("CanonicalQP: equality constraints are not supported")
            col = d[cp.settings.PARAM_PROB].var_id_to_col[variable.id]
            return d[cp.settings.P], np.array(d[cp.settings.Q], float), d[cp.settings.F], \
                np.array(d[cp.settings.G], float), col

        P, q0, F, u0, col = data_at(np.zeros(n_p))
        Mq, Mu = np.zeros((q0.size, n_p)), np.zeros((u0.size, n_p))
        for j in range(n_p):
            e = np.zeros(n_p)
            e[j] = 1.0
            _, q, _, u, _ = data_at(e)
            Mq[:, j], Mu[:, j] = q - q0, u - u0
        check = np.random.default_rng(0).standard_normal(n_p)  # fixed draw: a structural check
        Pc, qc, Fc, uc, _ = data_at(check)
        if (abs(Pc - P).max() > 0 or abs(Fc - F).max() > 0
                or not np.allclose(qc, q0 + Mq @ check, rtol=1e-9, atol=1e-12)
                or not np.allclose(uc, u0 + Mu @ check, rtol=1e-9, atol=1e-12)):
            raise ValueError("CanonicalQP: P or A depends on the parameters, or the data is not "
                             "affine in them")
        for p, v in zip(self.params, saved):
            p.value = v
        self.q0, self.Mq, self.u0, self.Mu = q0, Mq, u0, Mu
        self.sl = slice(col, col + int(variable.size))
        self.status_map = CvxpyOSQP.STATUS_MAP
        self.solver = osqp.OSQP()
        # rebuilt from (data, indices, indptr) as cvxpy does: OSQP needs 32-bit indices
        P, F = (sp.csc_matrix(M) for M in (P, F))
        P, F = (sp.csc_matrix((M.data, M.indices, M.indptr), shape=M.shape) for M in (P, F))
        self.solver.setup(P, q0, F, np.full(u0.size, -np.inf), u0, verbose=False, **solver_opts)

    def solve(self) -> tuple[np.ndarray | None, str]:
        """Solve at the parameters' current values.

        :return: ``(value of the variable, or None unless optimal; cvxpy status string)``
        """
        p = np.concatenate([np.ravel(prm.value) for prm in self.params])
        self.solver.update(q=self.q0 + self.Mq @ p, u=self.u0 + self.Mu @ p)
        res = self.solver.solve(raise_error=False)
        status = str(self.status_map.get(res.info.status_val, cp.SOLVER_ERROR))
        if status != cp.OPTIMAL or res.x is None:
            return None, status
        return np.array(res.x[self.sl], float), status


class CondensedMPC:
    """The parametrised MPC problem, built once (see the module docstring).

    :param design: the LQG design whose model, weights and Riccati solution are used
    :param settings: horizon, limits and penalties
    """

    def __init__(self, design: LQGDesign, settings: MPCSettings) -> None:
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
        cons = [cp.abs(self.U) <= 1.0,
                cp.abs(D @ self.U - cp.hstack([self.u_prev, np.zeros((N - 1) * m)])) <= step,
                cp.abs(e_pred) <= lim_e + self.s]
        obj = cp.quad_form(self.U, cp.psd_wrap(Hs)) + self.q @ self.U + w1 * cp.sum(self.s) \
            + w2 * cp.sum_squares(self.s)
        self.problem = cp.Problem(cp.Minimize(obj), cons)
        if not self.problem.is_dpp():
            raise RuntimeError("the MPC problem is not DPP: it would be re-canonicalised every "
                               "step")
        self._solver_opts = dict(solver=cp.OSQP, warm_start=True, eps_abs=st.eps_abs,
                                 eps_rel=st.eps_rel, max_iter=int(st.max_iter), polishing=True,
                                 verbose=False)
        self.qp = CanonicalQP(self.problem, [self.q, self.e0, self.u_prev], self.U,
                              {k: v for k, v in self._solver_opts.items()
                               if k in ("eps_abs", "eps_rel", "max_iter", "polishing")})

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
        # servo errors e_j = -theta_j (deviation coordinates), j = 1..N
        Ce = np.zeros((2, nz))
        Ce[:, :n] = -design.dm.C
        E = np.kron(np.eye(N + 1), Ce)[2:]
        self.design = design
        self.Phi, self.Gam = Phi, Gam
        self.F = Gam.T @ Qbar @ Phi + Sbar.T @ Phi  # linear term: 2 (F z0)' u
        self.Ephi, self.Egam = E @ Phi, E @ Gam
        self.H = 0.5 * (H + H.T)
        return self.H

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

    def set_parameters(self, z0: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> None:
        """Load the state-dependent parameters of one step.

        :param z0: LQR state ``[x - x_ref; xi; r_prev - r_ss]`` (SI)
        :param r_ss: steady command of the ramp (rad/s), shape (2,)
        :param r_prev: previous applied command (rad/s), shape (2,)
        """
        N, ru, es = self.N, self._ru, self._es
        Rss = np.tile(r_ss, N)
        # cost in u~ = U ru - Rss: u~' H u~ + 2 (F z0)' u~  ->  in U (scaled, up to a constant)
        lin = 2.0 * (self.F @ z0 - (self.H_scaled * self._Hs_scale / (ru * ru)) @ Rss)
        self.q.value = lin * ru / self._Hs_scale
        self.e0.value = (self.Ephi @ z0 - self.Egam @ Rss) / es
        self.u_prev.value = np.clip(r_prev / ru, -1.0, 1.0)

    def solve(self, z0: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray
              ) -> tuple[np.ndarray | None, str, float]:
        """Solve one step.

        :return: ``(r_0, status, solve_time_s)``; ``r_0`` (rad/s) is None when the solve failed
            or the first move violates the hard limits
        """
        self.set_parameters(z0, r_ss, r_prev)
        t0 = time.perf_counter()
        U = None
        try:
            U, status = self.qp.solve()
        except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
            status = f"solver_error: {type(exc).__name__}: {exc}"
        dt = time.perf_counter() - t0
        if status != cp.OPTIMAL or U is None:
            return None, status, dt
        u0 = np.asarray(U[:self.m], float)
        step = self.settings.rate_step / self._ru
        up = self.u_prev.value
        # OSQP meets constraints to ~eps_abs; more than 1 % of a rate step is a failed solve
        viol = max(float(np.max(np.abs(u0) - 1.0)), float(np.max(np.abs(u0 - up) - step)))
        if viol > 0.01 * step:
            return None, "limits_violated", dt
        u0 = np.clip(np.clip(u0, up - step, up + step), -1.0, 1.0)
        return u0 * self._ru, status, dt


class MPCController(LQGController):
    """The MPC behind the controller interface: the LQG's estimator, wind inference and
    integrator, with the constrained problem as the law and the LQG law as the fallback.

    ``info`` carries ``solve_time_s`` (the OSQP call), ``status`` and the episode's counts
    ``n_solves``, ``n_fallbacks`` and ``fallback_statuses`` (status -> count).

    :param env: the environment (or its config / an :class:`EnvSpec`)
    :param name: label, default ``"MPC"``
    :param config: MPC settings, default section ``mpc`` of ``configs/controllers.yaml``
    :param lqg_config: settings of the shared estimator/fallback, default section ``lqg``
    """

    def __init__(self, env: Any = None, name: str = "MPC", config: MPCConfig | None = None,
                 lqg_config: LQGConfig | None = None) -> None:
        cc = default_controllers_config()
        self.mpc_config = mcfg = config or cc.mpc
        lcfg = lqg_config or cc.lqg
        lcfg = dataclasses.replace(lcfg, shaper=mcfg.shaper,
                                   action_change_weight=mcfg.action_change_weight)
        super().__init__(env, name, lcfg)
        spec = self.spec
        # 0.1 % margin: the observed previous command is float32, the limiter checks in float64
        self.settings = MPCSettings(int(mcfg.horizon), spec.rate_limit * (1 - 1e-3),
                                    spec.rate_step * (1 - 1e-3),
                                    mcfg.error_soft_limit, mcfg.slack_weight_linear,
                                    mcfg.slack_weight_quadratic, mcfg.eps_abs, mcfg.eps_rel,
                                    int(mcfg.max_iter))
        self._mpcs: dict[int, CondensedMPC] = {}
        self.use_design(self.design)

    def use_design(self, design: LQGDesign) -> None:
        """Load a design; the MPC problem is built once per LQR state size (the direction-free
        and the inferred gust models differ in filter states) and re-pointed otherwise."""
        super().use_design(design)
        mpcs = getattr(self, "_mpcs", None)
        if mpcs is None:  # during the base-class constructor
            return
        nz = design.n_z
        if nz not in mpcs:
            mpcs[nz] = CondensedMPC(design, self.settings)
        else:
            mpcs[nz].load_design(design)
        self.mpc = mpcs[nz]

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self.n_solves = 0
        self.n_fallbacks = 0
        self.fallback_statuses: dict[str, int] = {}

    def fallback(self, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> np.ndarray:
        """The LQG command, clipped to the rate and rate-change limits."""
        r = self.lqr_command(z, r_ss)
        st = self.settings
        return np.clip(np.clip(r, r_prev - st.rate_step, r_prev + st.rate_step),
                       -st.rate_limit, st.rate_limit)

    def law(self, z: np.ndarray, r_ss: np.ndarray, r_prev: np.ndarray) -> np.ndarray:
        r, status, dt = self.mpc.solve(z, r_ss, r_prev)
        self.n_solves += 1
        if r is None:
            self.n_fallbacks += 1
            key = status.split(":")[0]
            self.fallback_statuses[key] = self.fallback_statuses.get(key, 0) + 1
            r = self.fallback(z, r_ss, r_prev)
        self.info.update({"mpc_solve_time_s": dt, "status": status, "n_solves": self.n_solves,
                          "n_fallbacks": self.n_fallbacks,
                          "fallback_statuses": dict(self.fallback_statuses)})
        return r
