"""The vector environment's compiled step (:mod:`dss14_env.envs.fused`) against the batched
pieces of :mod:`dss14_env.envs.core`, bit for bit: the two loops on random batches
(hypothesis; the compiled loops and their plain-Python form) with the edge cases drawn on
purpose -- signed zeros and actions at the limiter's bounds, absolute angles half a count
apart, errors and elevations exactly at the termination bounds, errors beyond the observation
bounds -- and the whole vector environment stepped both ways.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import dss14_env  # noqa: F401  (registers the ids)
from dss14_env.core.units import R2D, R2MD
from dss14_env.envs import fused
from dss14_env.envs.core import (
    StepConstants,
    limit_commands,
    observation,
    pointing_errors,
    read_encoders,
    reward,
    scored_errors,
    servo_errors,
    step_info,
    terminated,
)
from dss14_env.envs.vector import DSS14VectorEnv

K_NOISE = 4


def _kernels() -> list:
    """The loops as run: compiled (with numba) and their plain-Python form."""
    forms = [(fused.before_product, fused.after_product)]
    if fused.AVAILABLE:
        forms.append((fused.before_product.py_func, fused.after_product.py_func))
    return forms


@st.composite
def batches(draw) -> dict:
    """Constants and N rows of inputs with the edge cases of tests/test_env_core.py."""
    N = draw(st.integers(1, 6))
    scale = draw(st.floats(1e-4, 0.2))
    rl = draw(st.one_of(st.just(scale), st.floats(1e-4, 0.2)))
    el_lo = draw(st.floats(0.0, 0.7))
    k = StepConstants(draw(st.sampled_from([0.01, 0.02])), scale, rl, draw(st.floats(0.0, 0.05)), scale > rl,
                      draw(st.sampled_from([0.0, 2 * math.pi / 2**20, 2 * math.pi / 2**8])),
                      draw(st.sampled_from([0.0, 1e-6])), draw(st.floats(1e-3, 1e3)),
                      draw(st.floats(0.0, 10.0)),
                      draw(st.floats(0.0, 1e4)), (el_lo, el_lo + draw(st.floats(0.1, 0.8))),
                      draw(st.floats(-1.0, 1.0)), draw(st.floats(0.1, 4.0)), draw(st.booleans()))
    rows = []
    for _ in range(N):
        s_az = draw(st.floats(k.az_centre - k.az_half_range, k.az_centre + k.az_half_range))
        s_el = draw(st.floats(*k.el_limits))
        theta = np.array([draw(st.floats(-0.1, 0.1)), draw(st.floats(-0.1, 0.1))])
        if k.quantum and draw(st.booleans()):  # the absolute angle half a count between two
            theta[0] = k.quantum * (draw(st.integers(-10**5, 10**5)) + 0.5) - s_az
        if draw(st.booleans()):  # the elevation exactly at its lower limit
            theta[1] = k.el_limits[0] - s_el
        c = theta + np.array([draw(st.floats(-1e-2, 1e-2)), draw(st.floats(-1e-2, 1e-2))])
        if draw(st.booleans()):  # far off: terminating, observation clamped
            c[1] += draw(st.sampled_from([-1.0, 1.0])) * draw(st.floats(0.01, 3.0))
        e_pick = abs(float((c[0] - theta[0]) * R2MD))
        me = draw(st.sampled_from([e_pick, math.nextafter(e_pick, 0.0), math.nextafter(e_pick, math.inf),
                                   1e5]))
        rates = st.floats(-k.rate_limit, k.rate_limit)
        rp = np.array([draw(rates), draw(rates)])
        actions = st.one_of(st.floats(-1.0, 1.0), st.floats(-5.0, 5.0),
                            st.sampled_from([-1.0, 1.0, 0.0, -0.0]))
        a = np.array([draw(actions), draw(actions)])
        if draw(st.booleans()):  # the rate command exactly at the acceleration bound
            a[0] = float(np.clip((rp[0] + k.rate_step) / k.action_scale, -1.0, 1.0))
        if draw(st.booleans()):  # a zero action against a zero bound: the sign of the zero
            a[1], rp[1] = -0.0, k.rate_step
        rows.append(dict(start=(s_az, s_el), theta=theta, c=c, me=me, rp=rp, a=a,
                         point=[draw(st.floats(-0.1, 0.1)), draw(st.floats(-0.1, 0.1))],
                         cd=[draw(st.floats(-1.0, 1.0)), draw(st.floats(-1.0, 1.0))],
                         ap=[draw(st.floats(-1.0, 1.0)), draw(st.floats(-1.0, 1.0))],
                         em0=[draw(st.floats(-1e3, 1e3)), draw(st.floats(-1e3, 1e3))],
                         normals=[draw(st.floats(-4.0, 4.0)) for _ in range(K_NOISE + 2)],
                         hits=[draw(st.integers(0, 5)), draw(st.integers(0, 5))],
                         wind=[draw(st.floats(0.0, 25.0)), draw(st.floats(-7.0, 7.0))],
                         kappa=[draw(st.floats(-2.0, 2.0)), draw(st.floats(-2.0, 2.0))],
                         t_mean=[draw(st.floats(-1e6, 1e6)), draw(st.floats(-1e6, 1e6))]))
    stack = {key: np.array([r[key] for r in rows], float) for key in rows[0]}
    stack["hits"] = stack["hits"].astype(np.int64)
    return dict(k=k, perm=np.array(draw(st.permutations(range(N))), np.int64), xel=draw(st.floats(0.1, 1.0)),
                clamp_always=draw(st.booleans()), **stack)


def _pieces(d: dict) -> dict:
    """The batched pieces' results (as DSS14VectorEnv steps without the compiled loops)."""
    k = d["k"]
    a, r, rate_hit, acc_hit = limit_commands(d["a"], d["rp"], k)
    noise = d["normals"][:, K_NOISE:] * k.encoder_sigma if k.encoder_sigma else None
    rel = read_encoders(d["theta"], d["start"], noise, k)
    em, e = servo_errors(d["c"], rel), servo_errors(d["c"], d["theta"])
    term = terminated(e, d["theta"], d["start"], d["me"], k)
    pe = pointing_errors(d["c"], d["point"], d["xel"])
    rew = reward(scored_errors(e, pe, k), a, d["ap"], term, k)
    obs = observation(em, d["em0"], d["c"] * R2D, d["cd"] * (1.0 / k.rate_limit), rel, r,
                      bool(term.any()) or d["clamp_always"], k)
    hits = d["hits"].copy()
    hits[:, 0] += rate_hit
    hits[:, 1] += acc_hit
    info = step_info(e, em, pe, d["wind"], d["a"], r, rate_hit, acc_hit, hits)
    return dict(a=a, r=r, rate_hit=rate_hit, acc_hit=acc_hit, em=em, term=term, rew=rew, obs=obs, info=info,
                hits=hits)


def _loops(d: dict, before, after) -> dict:
    """The two loops' results on the same inputs, the product's rows laid out in slot order."""
    k, perm, N, n = d["k"], d["perm"], len(d["a"]), 3
    inv = np.argsort(perm)
    kc = fused.constants(k, d["xel"])
    Z = np.full((n + 4 + 2 * K_NOISE, N), np.nan)
    a, r = np.empty((N, 2)), np.empty((N, 2))
    rate_hit, acc_hit = np.empty(N, bool), np.empty(N, bool)
    kappa_s, t_mean_s = np.ascontiguousarray(d["kappa"][perm].T), np.ascontiguousarray(d["t_mean"][perm].T)
    before(d["a"], d["rp"], kc, perm, kappa_s, t_mean_s, d["normals"], True, n, K_NOISE, Z, a, r, rate_hit,
           acc_hit)
    # the product's input rows, in slot order
    np.testing.assert_array_equal(Z[:n], np.nan)
    np.testing.assert_array_equal(Z[n:n + 2], r[perm].T)
    np.testing.assert_array_equal(Z[n + 2:n + 4], t_mean_s)
    xs = d["normals"][perm, :K_NOISE].T
    np.testing.assert_array_equal(Z[n + 4:n + 4 + K_NOISE], xs * kappa_s[0])
    np.testing.assert_array_equal(Z[n + 4 + K_NOISE:], xs * kappa_s[1])
    Y = np.ascontiguousarray(np.concatenate([d["theta"], d["point"]], axis=1)[perm].T)
    obs, rew, term = np.empty((N, 12), np.float32), np.empty(N), np.empty(N, bool)
    em, info_f, info_i = np.empty((N, 2)), np.empty((10, N)), np.empty((2, N), np.int64)
    hits = d["hits"].copy()
    flags = after(Y, inv, d["c"], d["cd"], d["start"], d["normals"], K_NOISE, d["me"], a, d["ap"], d["em0"],
                  r, d["wind"], rate_hit, acc_hit, hits, kc, d["clamp_always"], obs, rew, term, em, info_f,
                  info_i)
    info = {**dict(zip(fused.INFO_FLOAT_ROWS, info_f, strict=True)),
            **dict(zip(fused.INFO_INT_ROWS, info_i, strict=True))}
    return dict(a=a, r=r, rate_hit=rate_hit, acc_hit=acc_hit, em=em, term=term, rew=rew, obs=obs, info=info,
                hits=hits, flags=flags)


def _same_bits(x: np.ndarray, y: np.ndarray, what: str) -> None:
    x, y = np.asarray(x), np.asarray(y)
    assert x.dtype == y.dtype and x.shape == y.shape, what
    assert x.tobytes() == y.tobytes(), f"{what}: {x!r} != {y!r}"  # signed zeros included


@given(batches())
def test_loops_equal_the_batched_pieces_bit_for_bit(d: dict) -> None:
    want = _pieces(d)
    for before, after in _kernels():
        got = _loops(d, before, after)
        for key in ("a", "r", "rate_hit", "acc_hit", "em", "term", "rew", "obs", "hits"):
            _same_bits(got[key], want[key], key)
        for key in (*fused.INFO_FLOAT_ROWS, *fused.INFO_INT_ROWS):
            _same_bits(got["info"][key], np.ascontiguousarray(want["info"][key]), key)
        assert got["flags"] == fused.ANY_TERMINATED * bool(want["term"].any())


@pytest.mark.parametrize("x, y", [(-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (1.0, 1.0), (-1.0, 2.0)])
def test_max_and_min_pick_the_operand_numpy_picks(x: float, y: float) -> None:
    # np.maximum / np.minimum return their second operand where the two compare equal
    for name, ref in (("_max", np.maximum), ("_min", np.minimum)):
        f = getattr(fused, name)
        for form in (f, getattr(f, "py_func", f)):
            want = np.array([ref(np.array([x] * 64), y)[0]])
            assert np.array([form(x, y)]).tobytes() == want.tobytes(), (name, x, y)


def test_a_non_finite_reward_is_flagged_and_the_hit_counts_kept() -> None:
    d = dict(k=StepConstants(0.02, 0.01, 0.005, 0.001, True, 0.0, 0.0, 10.0, 1.0, 1e4, (0.1, 1.5), 0.0, 4.6),
             perm=np.arange(2), xel=0.5, clamp_always=False, a=np.array([[1.0, 0.0], [0.0, 0.0]]),
             rp=np.zeros((2, 2)), theta=np.array([[0.0, 1.0], [np.inf, 1.0]]),
             start=np.array([[0.0, 0.2]] * 2),
             c=np.zeros((2, 2)), cd=np.zeros((2, 2)), me=np.array([1e5, 1e5]), point=np.zeros((2, 2)),
             ap=np.zeros((2, 2)), em0=np.zeros((2, 2)), normals=np.zeros((2, K_NOISE + 2)),
             hits=np.array([[1, 2], [3, 4]]), wind=np.zeros((2, 2)), kappa=np.ones((2, 2)),
             t_mean=np.zeros((2, 2)))
    for before, after in _kernels():
        got = _loops(d, before, after)
        assert got["flags"] & fused.NON_FINITE
        assert not np.isfinite(got["rew"][1])
        np.testing.assert_array_equal(got["hits"], d["hits"])


# ---------------------------------------------------------------------------- the whole environment
CASES = {
    "track-random-wind-encoder-noise": (dict(scenario="track", wind_speed_kmh="random",
                                             wind_direction="random", encoder_noise_mdeg=0.1), 0.02, 400),
    "hold-terminating-at-el-limit": (dict(scenario="hold", wind_speed_kmh="random", start_el_deg="random",
                                          start_el_range_deg=[6.05, 6.5]), -0.5, 400),
    "slew-exact-encoders-rate-clip": (dict(scenario="slew", wind_speed_kmh=30.0, encoder_bits=None,
                                           action_scale_deg_s=0.5, rate_limit_deg_s=0.2), 1.5, 300),
    "pointing-reward-terminating": (dict(reward="pointing", max_error_deg=0.002, wind_speed_kmh="random"),
                                    0.05, 256),
    "no-wind-random-params": (dict(wind_speed_kmh=0.0, randomize_params=True), 0.02, 200),
    "monopulse-late-held-terminating": (dict(sensors=["encoders", "monopulse"], encoder_noise_mdeg=0.1,
                                             monopulse_latency_s=0.06, monopulse_update_s=0.04,
                                             max_error_deg=0.002, wind_speed_kmh="random"), 0.05, 256),
}


def _run(compiled: bool, kw: dict, scale: float, T: int, N: int = 5, steps: int = 600) -> list:
    rng = np.random.default_rng(3)
    acts = (rng.uniform(-1.0, 1.0, (steps, N, 2)) * scale).astype(np.float32)
    acts[::23, 0] = -0.0
    venv = DSS14VectorEnv(num_envs=N, max_episode_steps=T, compiled=compiled, **kw)
    assert venv.compiled is compiled
    out = [venv.reset(seed=4)]
    for t in range(steps):
        out.append(venv.step(acts[t]))
    return out


def _flat(results: list) -> list:
    """(name, array) of every part of every step's result, info keys in their order."""
    flat = []
    for r in results:
        names = ("obs", "info") if len(r) == 2 else ("obs", "reward", "terminated", "truncated", "info")
        for name, part in zip(names, r, strict=True):
            if isinstance(part, dict):
                flat += [(key, np.asarray(part[key])) for key in part]
            else:
                flat.append((name, np.asarray(part)))
    return flat


@pytest.mark.parametrize("case", CASES)
def test_vector_env_compiled_equals_numpy_bit_for_bit(case: str) -> None:
    pytest.importorskip("numba")
    kw, scale, T = CASES[case]
    a, b = _flat(_run(True, kw, scale, T)), _flat(_run(False, kw, scale, T))
    assert [k for k, _ in a] == [k for k, _ in b]  # the same keys in the same order
    for (key, x), (_, y) in zip(a, b, strict=True):
        if x.dtype == object:
            assert x.tolist() == y.tolist(), key
        else:
            _same_bits(np.ascontiguousarray(x), np.ascontiguousarray(y), key)
    if case.endswith("terminating"):  # the episode ends (and the clamping) did happen
        assert any(key == "terminated" and x.any() for key, x in a)


def test_each_loop_is_compiled_once_whatever_the_case() -> None:
    # the arrays keep one layout and the scalars one type: no second compilation mid-run
    pytest.importorskip("numba")
    cases = list(CASES.values())
    _run(True, *cases[0], steps=60)
    seen = len(fused.before_product.signatures), len(fused.after_product.signatures)
    for kw, scale, T in cases[1:]:
        _run(True, kw, scale, T, steps=60)
    assert (len(fused.before_product.signatures), len(fused.after_product.signatures)) == seen


def test_compiled_needs_numba(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fused, "AVAILABLE", False)
    with pytest.raises(ValueError, match="compiled=True needs numba"):
        DSS14VectorEnv(num_envs=2, compiled=True)
    assert DSS14VectorEnv(num_envs=2).compiled is False


@pytest.mark.parametrize("bad", ["yes", 1.0, [True]])
def test_compiled_must_be_none_or_a_bool(bad) -> None:
    with pytest.raises(ValueError, match="compiled must be None, True or False"):
        DSS14VectorEnv(num_envs=2, compiled=bad)
