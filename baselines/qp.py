"""Repeated solves of one parametrised cvxpy QP: an OSQP fast path with ``Problem.solve`` behind it.

cvxpy states the problem and canonicalises it; :class:`ParametricQP` solves it again and again
for new parameter values.  The fast path, :class:`CanonicalQP`, keeps one OSQP workspace and
only updates its data vectors each solve.  It is the ONE place in the package that reads cvxpy
internals, namely

* ``Problem.get_problem_data(cvxpy.OSQP)``'s layout: the dict keys ``P, q, A, b, F, G`` of
  :mod:`cvxpy.settings` (cost ``x'Px/2 + q'x``, equalities ``Ax = b``, inequalities
  ``Fx <= G``) and ``param_prob.var_id_to_col`` (where a variable sits in ``x``);
* cvxpy's OSQP interface's status map (``osqp_qpif.OSQP.STATUS_MAP``, OSQP status value ->
  cvxpy status string);
* ``Leaf.save_value``, which stores a parameter's value without the ``value`` setter's
  projection check (:func:`set_values`);

and calls OSQP's 1.x Python API (``setup``, ``update(q=, u=)``, ``solve(raise_error=False)``).
It was checked on cvxpy 1.9.3 with osqp 1.1.3; ``pyproject.toml`` pins ``cvxpy>=1.9,<1.10``
and ``osqp>=1.1,<2``.  When the structure it expects is not there, the constructor raises
:class:`AdapterError` (``tests/test_baselines_qp.py`` builds it on a known problem, so a cvxpy
release that moves these internals fails that test loudly) and :class:`ParametricQP` solves
through :meth:`cvxpy.Problem.solve` instead.  A fast solve whose status is not ``optimal`` is
re-solved through :meth:`cvxpy.Problem.solve` too (its own OSQP workspace, same settings);
both paths solve the same problem to the same tolerances (tested).

>>> import cvxpy as cp
>>> x, p = cp.Variable(2), cp.Parameter(2)
>>> prob = cp.Problem(cp.Minimize(cp.sum_squares(x) - p @ x), [x <= 1.0])
>>> qp = ParametricQP(prob, [p], x, {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": True})
>>> p.value = np.array([1.0, 4.0])
>>> r = qp.solve()
>>> r.status, r.path, np.round(r.x, 6).tolist()
('optimal', 'osqp', [0.5, 1.0])
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import cvxpy as cp
import numpy as np
import osqp
import scipy.sparse as sp

#: the solve paths of :class:`ParametricQP`
PATH_FAST, PATH_CVXPY = "osqp", "cvxpy"


class AdapterError(RuntimeError):
    """cvxpy's canonical OSQP data does not have the structure :class:`CanonicalQP` reads."""


def osqp_data(problem: cp.Problem, variable: cp.Variable) -> tuple[Any, np.ndarray, Any, np.ndarray, int]:
    """``(P, q, F, G, column of variable)`` of cvxpy's OSQP data at the current parameter values.

    :raises AdapterError: if the data is not laid out as documented in the module docstring
    """
    try:
        data, _, _ = problem.get_problem_data(cp.OSQP)
        keys = cp.settings
        P, q, A, F, G = (data[k] for k in (keys.P, keys.Q, keys.A, keys.F, keys.G))
        col = data[keys.PARAM_PROB].var_id_to_col[variable.id]
    except (KeyError, AttributeError, TypeError) as exc:
        raise AdapterError(f"cvxpy's OSQP problem data has changed layout "
                           f"({type(exc).__name__}: {exc})") from exc
    n = q.shape[0]
    if not (sp.issparse(P) and sp.issparse(F) and P.shape == (n, n) and F.shape[1] == n
            and G.shape == (F.shape[0],)):
        raise AdapterError(f"cvxpy's OSQP data has unexpected shapes: P {P.shape}, q {q.shape}, "
                           f"F {F.shape}, G {np.shape(G)}")
    if A.shape[0]:
        raise AdapterError("equality constraints are not supported by the fast path")
    return P, np.array(q, float), F, np.array(G, float), int(col)


def osqp_status_map() -> dict[int, str]:
    """Cvxpy's map from OSQP status values to cvxpy status strings."""
    try:
        from cvxpy.reductions.solvers.qp_solvers.osqp_qpif import OSQP as CvxpyOSQP
        status_map = dict(CvxpyOSQP.STATUS_MAP)
    except (ImportError, AttributeError) as exc:
        raise AdapterError(f"cvxpy's OSQP interface has no STATUS_MAP ({exc})") from exc
    if status_map.get(1) != cp.OPTIMAL:
        raise AdapterError(f"cvxpy's OSQP status map does not map 1 to 'optimal': {status_map}")
    return status_map


def set_values(params: list[cp.Parameter], values: list[np.ndarray]) -> None:
    """Set the values of parameters without attributes (``cp.Parameter(shape)``), as their
    ``value`` setter would store them, without its projection check (about 0.1 ms a
    parameter: a fifth of an MPC step): each value is a float64 copy of its parameter's shape.
    A parameter with attributes (``nonneg``, ...) goes through the setter.

    :raises ValueError: as the setter: a value of another shape, or with a NaN (not real),
        naming the parameter
    """
    for p, v in zip(params, values, strict=True):
        a = np.array(v, dtype=np.float64)
        if a.shape != p.shape or np.isnan(a).any():
            raise ValueError(f"parameter {p.name()}: a real value of shape {p.shape}, got shape "
                             f"{a.shape}{' with NaN' if a.shape == p.shape else ''}")
        if any(p.attributes.values()):  # nonneg, bounds, ...: all falsy on a plain parameter
            p.value = a
        else:
            p.save_value(a)


class KeptData:
    """The canonical data of the problems a process has probed (:class:`CanonicalQP`), by key,
    the least recently used dropped beyond ``size``.
    """

    def __init__(self, size: int) -> None:
        self.size = int(size)
        self._data: OrderedDict[Any, tuple[Any, ...]] = OrderedDict()

    def get(self, key: Any) -> tuple[Any, ...] | None:
        """The data of ``key``, or None."""
        data = self._data.get(key)
        if data is not None:
            self._data.move_to_end(key)
        return data

    def put(self, key: Any, data: tuple[Any, ...]) -> None:
        """Keep ``data`` under ``key``."""
        self._data[key] = data
        self._data.move_to_end(key)
        while len(self._data) > self.size:
            self._data.popitem(last=False)

    def clear(self) -> None:
        """Forget every problem's data."""
        self._data.clear()

    def __len__(self) -> int:
        return len(self._data)


#: the canonical data of the problems this process has probed (:class:`CanonicalQP` ``key``)
CANONICAL_DATA = KeptData(64)


class CanonicalQP:
    """A DPP cvxpy problem, canonicalised once for OSQP, re-solved with new parameter values.

    At construction every parameter entry is probed (cvxpy's own ``get_problem_data`` with a
    unit value, the others zero) to get the affine maps ``q = q0 + Mq p``, ``u = u0 + Mu p``;
    a fixed random parameter vector then checks that ``P`` and the constraint matrix stay
    constant and the maps are exact (cvxpy's OSQP data has inequalities ``F x <= G`` only, so
    OSQP's lower bounds are ``-inf``).  One OSQP workspace is set up; :meth:`solve` updates
    ``q`` and ``u`` and solves, warm-started from the previous solution (OSQP's default).

    :param problem: DPP problem whose parameters enter only the linear cost and the right-hand
        sides of inequalities
    :param params: its parameters, in the order of the vector :meth:`solve` reads
    :param variable: the variable to return
    :param settings: OSQP settings (e.g. ``eps_abs``, ``eps_rel``, ``max_iter``, ``polishing``)
    :param key: what determines the problem entirely (its builder's inputs, e.g. a digest of
        its matrices), or None: the probed data is kept under it (:data:`CANONICAL_DATA`) and a
        problem of the same key takes it from there instead of probing again; each instance
        has its own OSQP workspace
    :raises AdapterError: if cvxpy's data is not as described, or not affine in the parameters
        with constant matrices
    """

    def __init__(self, problem: cp.Problem, params: list[cp.Parameter], variable: cp.Variable,
                 settings: dict[str, Any], key: Any = None) -> None:
        self.params = list(params)
        self.status_map = osqp_status_map()
        data = CANONICAL_DATA.get(key) if key is not None else None
        if data is None:
            data = self._probe(problem, variable)
            if key is not None:
                CANONICAL_DATA.put(key, data)
        P, self.q0, F, self.u0, self.Mq, self.Mu, col = data
        self.sl = slice(col, col + int(variable.size))
        self.n_variables, self.n_constraints = self.q0.size, self.u0.size
        self.solver = osqp.OSQP()
        self.solver.setup(P, self.q0, F, np.full(self.u0.size, -np.inf), self.u0, verbose=False,
                          **settings)

    def _probe(self, problem: cp.Problem, variable: cp.Variable) -> tuple[Any, ...]:
        """``(P, q0, F, u0, Mq, Mu, column)`` of the problem, probed and checked (the class)."""
        saved = [None if p.value is None else np.array(p.value, copy=True) for p in self.params]
        sizes = [int(p.size) for p in self.params]
        n_p = sum(sizes)

        def data_at(vec: np.ndarray) -> tuple[Any, np.ndarray, Any, np.ndarray, int]:
            k = 0
            for p, n in zip(self.params, sizes, strict=True):
                p.value = vec[k:k + n].reshape(p.shape)
                k += n
            return osqp_data(problem, variable)

        try:
            P, q0, F, u0, col = data_at(np.zeros(n_p))
            Mq, Mu = np.zeros((q0.size, n_p)), np.zeros((u0.size, n_p))
            for j, e in enumerate(np.eye(n_p)):
                _, q, _, u, _ = data_at(e)
                Mq[:, j], Mu[:, j] = q - q0, u - u0
            check = np.random.default_rng(0).standard_normal(n_p)  # fixed draw: a structural check
            Pc, qc, Fc, uc, _ = data_at(check)
        finally:
            for p, v in zip(self.params, saved, strict=True):
                p.value = v
        if (Pc.shape != P.shape or Fc.shape != F.shape or abs(Pc - P).max() > 0 or abs(Fc - F).max() > 0
                or not np.allclose(qc, q0 + Mq @ check, rtol=1e-9, atol=1e-12)
                or not np.allclose(uc, u0 + Mu @ check, rtol=1e-9, atol=1e-12)):
            raise AdapterError("P or the constraint matrix depends on the parameters, or the data "
                               "is not affine in them")
        # rebuilt from (data, indices, indptr) as cvxpy does: OSQP needs 32-bit indices
        P, F = (sp.csc_matrix(M) for M in (P, F))
        P, F = (sp.csc_matrix((M.data, M.indices, M.indptr), shape=M.shape) for M in (P, F))
        for a in (P.data, P.indices, P.indptr, F.data, F.indices, F.indptr, q0, u0, Mq, Mu):
            a.setflags(write=False)  # shared between the problems of one key
        return P, q0, F, u0, Mq, Mu, col

    def warm_start(self, x: np.ndarray) -> None:
        """Start the next solve from ``x`` for the variable, every other variable and every dual
        at zero: the solution of a problem none of whose constraints is active, when the other
        variables are zero there (e.g. non-negative slacks under a positive penalty).

        :raises ValueError: if ``x`` is not a finite vector of the variable's size
        """
        v = np.asarray(x, float)
        if v.shape != (self.sl.stop - self.sl.start,) or not np.isfinite(v).all():
            raise ValueError(f"warm start: a finite vector of {self.sl.stop - self.sl.start} values, "
                             f"got shape {v.shape}")
        full = np.zeros(self.n_variables)
        full[self.sl] = v
        self.solver.warm_start(x=full, y=np.zeros(self.n_constraints))

    def solve(self) -> tuple[np.ndarray | None, str]:
        """Solve at the parameters' current values.

        :return: ``(value of the variable or None unless optimal, cvxpy status string)``
        """
        p = np.concatenate([np.ravel(prm.value) for prm in self.params])
        self.solver.update(q=self.q0 + self.Mq @ p, u=self.u0 + self.Mu @ p)
        res = self.solver.solve(raise_error=False)
        status = str(self.status_map.get(res.info.status_val, cp.SOLVER_ERROR))
        if status != cp.OPTIMAL or res.x is None:
            return None, status
        return np.array(res.x[self.sl], float), status


@dataclass(frozen=True)
class QPResult:
    """One solve of :class:`ParametricQP`.

    :param x: the variable's value, None unless ``status`` is optimal
    :param status: cvxpy status string of the solve that produced ``x`` (or of the last try)
    :param path: ``"osqp"`` (fast path) or ``"cvxpy"`` (:meth:`cvxpy.Problem.solve`)
    :param fast_status: status of the fast solve when it was re-solved through cvxpy, else None
    """

    x: np.ndarray | None
    status: str
    path: str
    fast_status: str | None = None


class ParametricQP:
    """Solve a DPP problem for new parameter values: :class:`CanonicalQP`, else ``Problem.solve``.

    :param problem: the DPP problem
    :param params: its parameters (order of :class:`CanonicalQP`)
    :param variable: the variable whose value :meth:`solve` returns
    :param settings: OSQP settings, used by both paths
    :param fast: try the fast path (default True); False always uses ``Problem.solve``
    :param key: what determines the problem entirely, or None (:class:`CanonicalQP`)
    """

    def __init__(self, problem: cp.Problem, params: list[cp.Parameter], variable: cp.Variable,
                 settings: dict[str, Any], fast: bool = True, key: Any = None) -> None:
        self.problem, self.variable = problem, variable
        self.settings = dict(settings)
        self.fast: CanonicalQP | None = None
        #: why the fast path is off (None while it is on)
        self.adapter_error: str | None = "disabled" if not fast else None
        if fast:
            try:
                self.fast = CanonicalQP(problem, params, variable, self.settings, key)
            except AdapterError as exc:
                self.adapter_error = str(exc)

    def warm_start(self, x: np.ndarray) -> None:
        """Start the fast path's next solve from ``x`` (:meth:`CanonicalQP.warm_start`); no-op
        without the fast path (``Problem.solve`` warm-starts from its own last solve).
        """
        if self.fast is not None:
            self.fast.warm_start(x)

    def solve_cvxpy(self) -> tuple[np.ndarray | None, str]:
        """Solve through :meth:`cvxpy.Problem.solve` (OSQP, warm-started by cvxpy).

        :return: ``(value or None unless optimal, status)``; a solver exception gives the status
            ``"solver_error: <message>"``
        """
        try:
            self.problem.solve(solver=cp.OSQP, warm_start=True, verbose=False, **self.settings)
        except cp.error.SolverError as exc:
            return None, f"solver_error: {exc}"
        status = str(self.problem.status)
        if status != cp.OPTIMAL or self.variable.value is None:
            return None, status
        return np.array(self.variable.value, float), status

    def solve(self) -> QPResult:
        """Solve at the parameters' current values (fast path first, see the class)."""
        if self.fast is None:
            x, status = self.solve_cvxpy()
            return QPResult(x, status, PATH_CVXPY)
        x, status = self.fast.solve()
        if status == cp.OPTIMAL:
            return QPResult(x, status, PATH_FAST)
        x, status2 = self.solve_cvxpy()
        return QPResult(x, status2, PATH_CVXPY, fast_status=status)
