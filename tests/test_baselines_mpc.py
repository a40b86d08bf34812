"""The cvxpy MPC: DPP, equivalence with the LQR when unconstrained, constraints on a slew, the
fast path against cvxpy's own solve, the LQG fallback and its record (baselines/mpc.py)."""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pytest

from dss14_env.baselines.interface import ControlInterface
from dss14_env.baselines.lqg import lqg_design_from_config
from dss14_env.baselines.mpc import CondensedMPC, MPCController, MPCSettings, MPCStep
from dss14_env.bench.runner import run_episode
from dss14_env.core.units import AXES, DEG, KMH, MDEG
from dss14_env.envs.env import DSS14Env


@pytest.fixture(scope="module")
def spec() -> ControlInterface:
    return ControlInterface.default()


@pytest.fixture(scope="module")
def mpc(spec) -> CondensedMPC:
    d = lqg_design_from_config(spec, wind=(50 * KMH, "front"))
    return CondensedMPC(d, MPCSettings(20, spec.rate_limit, spec.rate_step, 10 * MDEG, 10.0, 1.0))


def test_problem_is_dpp_and_built_once(mpc) -> None:
    assert mpc.problem.is_dpp()
    params = {p.name() for p in mpc.problem.parameters()}
    assert params == {"q", "e_free", "r_prev"}
    assert len(mpc.problem.variables()) == 2  # commands and slacks only: condensed


def test_canonical_qp_has_no_epigraph_variables(mpc) -> None:
    """The bounds are pairs of inequalities: OSQP sees the 2 N m commands and slacks only (an
    abs() bound would add a free epigraph variable per entry, a degenerate QP)."""
    assert mpc.qp.fast is not None, mpc.qp.adapter_error
    assert mpc.qp.fast.n_variables == 2 * mpc.N * mpc.m
    assert mpc.qp.fast.n_constraints == 7 * mpc.N * mpc.m  # 2 rate, 2 rate change, 2 error, slack >= 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_unconstrained_mpc_equals_the_lqr(mpc, seed: int) -> None:
    """Small state, no active constraint: the first move is the LQR's (terminal cost = P)."""
    rng = np.random.default_rng(seed)
    d = mpc.design
    z = np.zeros(d.n_z)
    z[:2] = rng.normal(size=2) * 0.05 * MDEG
    r_prev = rng.normal(size=2) * 1e-5
    r_ss = np.zeros(2)
    z[-2:] = r_prev - r_ss
    r_lqr = r_ss - d.K @ z
    assume = np.all(np.abs(r_lqr - r_prev) < 0.5 * mpc.settings.rate_step)
    assert assume, "test state should leave the constraints inactive"
    res = mpc.solve(z, r_ss, r_prev)
    assert res.status == cp.OPTIMAL
    assert res.r == pytest.approx(r_lqr, abs=1e-3 * mpc.settings.rate_step)


def test_large_error_respects_the_rate_change_limit(mpc) -> None:
    z = np.zeros(mpc.design.n_z)
    z[:2] = -0.1 * DEG
    res = mpc.solve(z, np.zeros(2), np.zeros(2))
    assert res.status == cp.OPTIMAL
    assert np.all(np.abs(res.r) <= mpc.settings.rate_step * (1 + 1e-9))
    assert np.all(res.r > 0.99 * mpc.settings.rate_step)  # and uses it fully


@pytest.mark.parametrize("bad", [{"horizon": 1}, {"rate_limit": 0.0}, {"slack_linear": -1.0},
                                 {"eps_abs": 0.0}, {"max_iter": 0}])
def test_settings_validated(bad: dict) -> None:
    kw = {**dict(horizon=20, rate_limit=1e-3, rate_step=1e-5, error_soft_limit=1e-4,
                 slack_linear=1.0, slack_quadratic=1.0), **bad}
    with pytest.raises(ValueError, match=next(iter(bad))):
        MPCSettings(**kw)


# ------------------------------------------------------------------ against the environment
@pytest.fixture(scope="module")
def slew_episode() -> tuple:
    env = DSS14Env(scenario="slew", slew_deg=1.0, wind_speed_kmh=30.0, wind_direction="side")
    ctrl = MPCController(env)
    m = run_episode(ctrl, env, seed=0, steps=900)
    return m, ctrl


def test_mpc_slew_needs_no_limiter(slew_episode) -> None:
    m, _ = slew_episode
    assert m["limit_hits"] == {"rate": 0, "accel": 0}


@pytest.mark.parametrize("axis", AXES)
def test_mpc_slew_within_rate_and_acceleration(slew_episode, axis: str) -> None:
    m, _ = slew_episode
    r = m["rate_command_deg_s"][axis]
    assert r["peak"] <= 0.25 * (1 + 1e-6)
    assert r["peak_accel_deg_s2"] <= 0.2 * (1 + 1e-4)
    assert r["peak"] > 0.05  # it did move


def test_mpc_slew_arrives_without_windup(slew_episode) -> None:
    m, ctrl = slew_episode
    assert not m["terminated"] and m["fallbacks"] == 0
    assert m["servo_error_mdeg"]["el"]["max"] < 200.0


def _hold_env() -> DSS14Env:
    return DSS14Env(scenario="hold", wind_speed_kmh=50.0, wind_direction="front")


def _reference_solution(cm: CondensedMPC) -> np.ndarray:
    """cvxpy's own solve of the problem at its parameters, far tighter than the controller's."""
    cm.problem.solve(solver=cp.OSQP, eps_abs=1e-9, eps_rel=1e-9, max_iter=200000, polishing=True,
                     warm_start=False)
    assert cm.problem.status == cp.OPTIMAL
    return np.array(cm.U.value)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_canonical_qp_equals_cvxpy_solve(mpc, seed: int) -> None:
    """The per-step OSQP update path (warm-started from whatever the earlier tests left) solves
    the problem itself, optimally, to cvxpy's own solution (small and large states; the
    rate-change limit is active in both)."""
    rng = np.random.default_rng(seed)
    cm = mpc
    for scale in (1e-7, 1e-4):
        z0 = rng.standard_normal(cm.nz) * scale
        r_prev = rng.uniform(-1, 1, 2) * cm.settings.rate_limit * 0.5
        cm.set_parameters(z0, np.zeros(2), r_prev)
        res = cm.qp.solve()
        assert (res.status, res.path) == (cp.OPTIMAL, "osqp")
        np.testing.assert_allclose(res.x, _reference_solution(cm), atol=1e-6)


def test_fast_solve_that_is_not_optimal_is_resolved_through_cvxpy(mpc) -> None:
    """A fast solve stopped by its iteration cap is re-solved by Problem.solve (same settings),
    with the same solution; the controller records the re-solve."""
    cm = mpc
    rng = np.random.default_rng(7)
    cm.set_parameters(rng.standard_normal(cm.nz) * 1e-4, np.zeros(2), np.array([1e-3, -1e-3]))
    cm.qp.fast.solver.update_settings(max_iter=1)
    try:
        res = cm.qp.solve()
    finally:
        cm.qp.fast.solver.update_settings(max_iter=cm.settings.max_iter)
    assert res.path == "cvxpy" and res.fast_status != cp.OPTIMAL and res.status == cp.OPTIMAL
    np.testing.assert_allclose(res.x, _reference_solution(cm), atol=1e-6)


def test_mpc_through_problem_solve_gives_the_fast_paths_actions() -> None:
    """The same episode with the fast path off (Problem.solve every step) gives the same actions."""
    env = DSS14Env(scenario="step", step_deg=0.05, wind_speed_kmh=30.0, wind_direction="side")
    fast, slow = MPCController(env), MPCController(env, fast=False)
    assert slow.problem_for(slow.design).qp.fast is None
    obs, _ = env.reset(seed=2)
    fast.reset(2)
    slow.reset(2)
    for _ in range(120):  # the step at 1 s: constraints become active
        a, b = fast.act(obs), slow.act(obs)
        np.testing.assert_allclose(a, b, atol=1e-5)
        obs, *_ = env.step(a)
    assert slow.info["qp_path"] == "cvxpy" and fast.info["qp_path"] == "osqp"
    assert fast.info["n_fallbacks"] == slow.info["n_fallbacks"] == 0


def test_fallback_on_solver_exception(monkeypatch) -> None:
    env = _hold_env()
    ctrl = MPCController(env, shortcut=False)  # every step solves the QP
    obs, _ = env.reset(seed=0)
    ctrl.reset(0)
    ctrl.act(obs)  # selects the design and its problem

    def boom(*args, **kwargs):
        raise cp.error.SolverError("forced failure")
    monkeypatch.setattr(ctrl.problem_for(ctrl.design).qp, "solve", boom)
    hits = 0
    for _ in range(20):
        obs, _, terminated, _, info = env.step(ctrl.act(obs))
        assert not terminated
        hits += int(info["accel_limited"]) + int(info["rate_limited"])
    assert ctrl.info["n_fallbacks"] == 20
    assert ctrl.info["fallback_statuses"] == {"solver_error": 20}
    assert [f["step"] for f in ctrl.info["fallbacks"]] == list(range(1, 21))
    assert all(f["status"].startswith("solver_error: SolverError") for f in ctrl.info["fallbacks"])
    assert hits == 0  # the fallback is clipped to the limits


def test_fallback_on_infeasible_problem_equals_clipped_lqg(monkeypatch) -> None:
    env = _hold_env()
    ctrl = MPCController(env)
    obs, _ = env.reset(seed=1)
    ctrl.reset(1)
    ctrl.act(obs)
    cm = ctrl.problem_for(ctrl.design)
    real = cm.parameters

    def impossible(z0, r_ss, r_prev):  # a previous command beyond the rate limit: |U_0| <= 1 and
        q, e_free, _ = real(z0, r_ss, r_prev)  # |U_0 - u_prev| <= step cannot both hold
        return q, e_free, np.array([5.0, 5.0])
    monkeypatch.setattr(cm, "parameters", impossible)
    a = ctrl.act(obs)
    assert ctrl.info["status"] == cp.INFEASIBLE and ctrl.info["n_fallbacks"] == 1
    assert ctrl.info["fallbacks"] == [{"step": 1, "status": cp.INFEASIBLE}]
    assert ctrl.info["resolves"] == [{"step": 1, "status": cp.INFEASIBLE}]  # fast path first
    # the action is the LQG law of the same state, clipped to the limits
    r_prev = obs[10:12] * ctrl.interface.rate_limit
    assert np.all(np.abs(a * ctrl.interface.action_scale - r_prev) <= ctrl.interface.rate_step * (1 + 1e-6))


def test_fallbacks_reported_per_episode_through_the_runner(monkeypatch) -> None:
    env = _hold_env()
    ctrl = MPCController(env)
    calls = {"n": 0}
    real = CondensedMPC.solve

    def flaky(self, *a):
        calls["n"] += 1
        if calls["n"] % 10 == 0:
            return MPCStep(None, "forced", 0.0, "osqp")
        return real(self, *a)
    monkeypatch.setattr(CondensedMPC, "solve", flaky)
    m = run_episode(ctrl, env, seed=0, steps=100)
    assert m["fallbacks"] == 10 and not m["terminated"] and m["n_steps"] == 100
    assert ctrl.info["fallbacks"] == [{"step": k, "status": "forced"} for k in range(9, 100, 10)]
    ctrl.reset(1)  # a new episode starts a new record
    assert ctrl.fallbacks == []


def test_mpc_is_not_batchable() -> None:
    ctrl = MPCController(None)
    assert not ctrl.batchable
    with pytest.raises(NotImplementedError, match="not batchable"):
        ctrl.reset_batch(2)
    with pytest.raises(NotImplementedError, match="not batchable"):
        ctrl.act_batch(np.zeros((1, 12)))


# ------------------------------------------------------------------ the unconstrained shortcut
def _tight_solution(cm: CondensedMPC) -> np.ndarray:
    """The QP at its parameters solved by an interior-point solver (Clarabel), tightly: an
    independent reference for the shortcut."""
    cm.problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    assert cm.problem.status == cp.OPTIMAL
    return np.array(cm.U.value)


def _load(cm: CondensedMPC, q: np.ndarray, e0: np.ndarray, u_prev: np.ndarray) -> None:
    cm.q.value, cm.e0.value, cm.u_prev.value = q, e0, u_prev


def test_shortcut_equals_the_qp_solution_where_it_is_taken(mpc) -> None:
    """On random states, previous commands and ramps, wherever the unconstrained minimiser is
    taken it is the QP's optimum (Clarabel, tight) to solver tolerance, and the step returns
    its first move; most of the draws take it (the test is not vacuous)."""
    rng = np.random.default_rng(11)
    taken = 0
    for _ in range(40):
        z0 = rng.standard_normal(mpc.nz) * 10.0 ** rng.uniform(-8, -5)
        r_ss = rng.uniform(-1, 1, 2) * 0.5 * mpc.settings.rate_limit
        r_prev = r_ss + rng.uniform(-1, 1, 2) * 0.2 * mpc.settings.rate_step
        z0[-2:] = r_prev - r_ss
        mpc.set_parameters(z0, r_ss, r_prev)
        U = mpc.unconstrained(*mpc.parameters(z0, r_ss, r_prev))
        if U is None:
            continue
        taken += 1
        np.testing.assert_allclose(U, _tight_solution(mpc), atol=1e-8)
        res = mpc.solve(z0, r_ss, r_prev)
        assert (res.status, res.path) == (cp.OPTIMAL, "unconstrained")
        np.testing.assert_allclose(res.r, U[:2] * mpc.settings.rate_limit, rtol=1e-12, atol=0)
    assert taken >= 20


def _scaled_bounds(cm: CondensedMPC) -> tuple[np.ndarray, float, float]:
    """``(Eg, rate step, error bound)`` of the problem in its scaled units (the module docstring)."""
    ru, es = cm.settings.rate_limit, cm.design.weights.error_scale
    return cm.Egam * ru / es, cm.settings.rate_step / ru, cm.settings.error_soft_limit / es


def _feasible_target(cm: CondensedMPC) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parameters whose unconstrained minimiser is a chosen command plan well inside every
    bound: ``(U_target, q, e0)`` with ``q = -2 H U_target`` and zero predicted errors."""
    N, m = cm.N, cm.m
    Eg, step, _ = _scaled_bounds(cm)
    U = np.tile([0.5, -0.3], N) + np.repeat(np.linspace(0.0, 0.2 * step * N, N), m)
    q = -2.0 * cm.H_scaled @ U
    e0 = -Eg @ U
    return U, q, e0


@pytest.mark.parametrize("case", ["inside", "rate", "accel_first", "accel_later", "error"])
def test_shortcut_taken_exactly_when_every_constraint_holds(mpc, case: str) -> None:
    """The minimiser of a chosen plan is taken when it is inside every bound; pushing it just
    past one bound (the rate, the acceleration from the previous command or within the horizon,
    a predicted error) sends the step to the QP, whose solution then differs from the plan (the
    plan was not the optimum: the check matters)."""
    cm, N, m = mpc, mpc.N, mpc.m
    Eg, step, lim_e = _scaled_bounds(cm)
    U, q, e0 = _feasible_target(cm)
    u_prev = U[:m].copy()
    if case == "rate":
        U = U.copy()
        U[0::m] += 1.02 - U[0::m].max()        # one axis past the rate limit, same increments
        u_prev, q, e0 = U[:m].copy(), -2.0 * cm.H_scaled @ U, -Eg @ U
    elif case == "accel_first":
        u_prev = u_prev + [1.02 * step, 0.0]
    elif case == "accel_later":
        U = U.copy()
        U[(N // 2) * m:] += [1.02 * step, 0.0] * (N - N // 2)  # a jump half-way along the horizon
        q, e0 = -2.0 * cm.H_scaled @ U, -Eg @ U
    elif case == "error":
        e0 = e0.copy()
        e0[3] += 1.02 * lim_e
    _load(cm, q, e0, u_prev)
    got = cm.unconstrained(q, e0, u_prev)
    if case == "inside":
        assert got is not None
        np.testing.assert_allclose(got, U, atol=1e-12)
        np.testing.assert_allclose(_tight_solution(cm), U, atol=1e-8)
        return
    assert got is None
    x, status, path, _ = cm.solve_qp()
    assert (status, path) == (cp.OPTIMAL, "osqp")
    ref = _tight_solution(cm)
    np.testing.assert_allclose(x, ref, atol=1e-5)
    assert np.max(np.abs(ref - U)) > 1e-4  # the push is 2 % of a bound, OSQP meets 1e-5


def test_shortcut_and_qp_every_step_give_the_same_actions() -> None:
    """A 50 km/h hold, both controllers fed the same observations: with the shortcut (most
    steps) and with a QP every step the actions agree to OSQP's tolerance; the episode's record
    counts each step's path."""
    env = _hold_env()
    on, off = MPCController(env), MPCController(env, shortcut=False)
    obs, _ = env.reset(seed=3)
    on.reset(3)
    off.reset(3)
    for _ in range(300):
        a, b = on.act(obs), off.act(obs)
        np.testing.assert_allclose(a, b, atol=1e-5)
        obs, *_ = env.step(b)
    paths = on.info["qp_paths"]
    assert set(paths) == {"unconstrained", "osqp"} and paths["unconstrained"] > paths["osqp"]
    assert sum(paths.values()) == on.info["n_solves"] == 300
    assert off.info["qp_paths"] == {"osqp": 300}
    assert on.info["n_fallbacks"] == off.info["n_fallbacks"] == 0
