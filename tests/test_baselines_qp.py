"""The cvxpy adapter of baselines/qp.py: its structural check on a known problem (fails loudly
when a cvxpy release moves the internals it reads), and Problem.solve as the automatic fallback."""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pytest

from dss14_env.baselines import qp as qp_module
from dss14_env.baselines.qp import AdapterError, CanonicalQP, ParametricQP, set_values

SETTINGS = {"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iter": 20000, "polishing": True}


def _known_problem() -> tuple[cp.Problem, list[cp.Parameter], cp.Variable]:
    """min |x|^2 - p'x  s.t.  -1 <= x <= 1,  x_0 + x_1 <= b: parameters in q and u only."""
    x = cp.Variable(3, name="x")
    p, b = cp.Parameter(3, name="p"), cp.Parameter(name="b")
    prob = cp.Problem(cp.Minimize(cp.sum_squares(x) - p @ x), [x <= 1.0, -x <= 1.0, x[0] + x[1] <= b])
    return prob, [p, b], x


def _solution(p: np.ndarray, b: float) -> np.ndarray:
    """The problem's solution, by hand: x = clip(p/2, -1, 1), then the coupling constraint."""
    x = np.clip(p / 2, -1.0, 1.0)
    if x[0] + x[1] > b:  # KKT with the coupling active (here the box stays inactive)
        lam = x[0] + x[1] - b
        x[:2] -= lam / 2
    return x


def test_adapter_structure_on_a_known_problem() -> None:
    """cvxpy's OSQP data of the known problem has the layout the adapter reads: 3 variables,
    3 + 3 + 1 inequality rows, data affine in the parameters.  A cvxpy release that changes it
    fails here (AdapterError names what moved)."""
    prob, params, x = _known_problem()
    fast = CanonicalQP(prob, params, x, SETTINGS)
    assert (fast.n_variables, fast.n_constraints) == (3, 7)
    assert fast.Mq.shape == (3, 4) and fast.Mu.shape == (7, 4)
    assert qp_module.osqp_status_map()[1] == cp.OPTIMAL


@pytest.mark.parametrize("p, b", [([1.0, 0.5, -4.0], 10.0), ([1.0, 0.5, -4.0], 0.2), ([3.0, 3.0, 0.0], -0.5)])
def test_fast_path_solves_the_known_problem(p: list, b: float) -> None:
    prob, params, x = _known_problem()
    qp = ParametricQP(prob, params, x, SETTINGS)
    params[0].value, params[1].value = np.array(p), b
    res = qp.solve()
    assert (res.status, res.path) == (cp.OPTIMAL, "osqp")
    np.testing.assert_allclose(res.x, _solution(np.array(p), b), atol=1e-7)


def test_adapter_that_cannot_be_built_falls_back_to_problem_solve(monkeypatch) -> None:
    def moved(problem, variable):
        raise AdapterError("cvxpy's OSQP problem data has changed layout (KeyError: 'param_prob')")
    monkeypatch.setattr(qp_module, "osqp_data", moved)
    prob, params, x = _known_problem()
    qp = ParametricQP(prob, params, x, SETTINGS)
    assert qp.fast is None and "changed layout" in qp.adapter_error
    params[0].value, params[1].value = np.array([1.0, 0.5, -4.0]), 0.2
    res = qp.solve()
    assert (res.status, res.path) == (cp.OPTIMAL, "cvxpy")
    np.testing.assert_allclose(res.x, _solution(np.array([1.0, 0.5, -4.0]), 0.2), atol=1e-7)


def test_parameter_in_the_quadratic_term_is_refused() -> None:
    """P must not depend on the parameters (the fast path updates q and u only)."""
    x = cp.Variable(2)
    w = cp.Parameter(nonneg=True)
    prob = cp.Problem(cp.Minimize(w * cp.sum_squares(x) - cp.sum(x)), [x <= 1.0])
    with pytest.raises(AdapterError, match="depends on the parameters"):
        CanonicalQP(prob, [w], x, SETTINGS)
    w.value = 2.0
    res = ParametricQP(prob, [w], x, SETTINGS).solve()  # falls back, same problem solved
    assert res.path == "cvxpy"
    np.testing.assert_allclose(res.x, [0.25, 0.25], atol=1e-7)


def test_equality_constraints_are_refused() -> None:
    x = cp.Variable(2)
    p = cp.Parameter(2)
    prob = cp.Problem(cp.Minimize(cp.sum_squares(x) - p @ x), [cp.sum(x) == 1.0])
    with pytest.raises(AdapterError, match="equality"):
        CanonicalQP(prob, [p], x, SETTINGS)


def test_set_values_stores_what_the_value_setter_stores() -> None:
    p, q = cp.Parameter(3), cp.Parameter(3)
    v = np.array([1.0, -np.inf, 2.5])
    set_values([p], [v])
    q.value = v
    np.testing.assert_array_equal(p.value, q.value)
    assert p.value.dtype == q.value.dtype
    v[0] = 7.0  # a copy is stored
    assert p.value[0] == 1.0
    with pytest.raises(ValueError, match="shape"):
        set_values([p], [np.zeros(2)])
    with pytest.raises(ValueError, match="NaN"):
        set_values([p], [np.array([0.0, np.nan, 0.0])])
    with pytest.raises(ValueError):  # an attribute is still enforced by the setter
        set_values([cp.Parameter(2, nonneg=True)], [np.array([-1.0, 0.0])])


def test_a_problem_of_a_kept_key_is_not_probed_again_and_solves_the_same(monkeypatch) -> None:
    qp_module.CANONICAL_DATA.clear()
    probes = []
    real = qp_module.osqp_data
    monkeypatch.setattr(qp_module, "osqp_data", lambda *a: probes.append(1) or real(*a))
    solutions = []
    for _ in range(2):
        prob, params, x = _known_problem()
        fast = CanonicalQP(prob, params, x, SETTINGS, key="known")
        n_probed = len(probes)
        params[0].value, params[1].value = np.array([1.0, 1.0, -3.0]), 0.5
        solutions.append(fast.solve()[0])
    assert n_probed > 0 and len(probes) == n_probed  # the second problem was not probed
    np.testing.assert_array_equal(solutions[0], solutions[1])
    np.testing.assert_allclose(solutions[0], _solution(np.array([1.0, 1.0, -3.0]), 0.5), atol=1e-6)
    assert len(qp_module.CANONICAL_DATA) == 1


def test_warm_start_from_a_point_gives_the_same_solution() -> None:
    """A solve started from a given point (duals zero) reaches the same optimum; a point of
    the wrong size or not finite is refused, naming what was expected."""
    prob, params, x = _known_problem()
    qp = ParametricQP(prob, params, x, SETTINGS)
    params[0].value, params[1].value = np.array([3.0, 3.0, 0.0]), -0.5
    qp.warm_start(np.array([0.9, -0.9, 0.5]))
    res = qp.solve()
    assert (res.status, res.path) == (cp.OPTIMAL, "osqp")
    np.testing.assert_allclose(res.x, _solution(np.array([3.0, 3.0, 0.0]), -0.5), atol=1e-7)
    for bad in (np.zeros(2), np.array([0.0, np.nan, 0.0])):
        with pytest.raises(ValueError, match="warm start: a finite vector of 3 values"):
            qp.warm_start(bad)
