"""The single environment's scalar step (:func:`dss14_env.envs.core.step_1`) against the batched
pieces of :mod:`dss14_env.envs.core` that the vector environment runs, piece by piece and bit
for bit, on random inputs (hypothesis) with the edge cases drawn on purpose: actions at and
beyond the limiter's bounds, rate commands exactly at the acceleration bound, encoder angles
exactly half a count apart, servo errors and elevations exactly at the termination bounds, and
errors beyond the observation bounds (clamping).

``HYPOTHESIS_PROFILE=dss14-slow`` (or the ``slow`` tests below) runs 1,000+ examples per property.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dss14_env.core.units import R2D, R2MD
from dss14_env.envs.core import (
    OBS_ERROR_BOUND,
    ScalarState,
    StepConstants,
    as_actions,
    limit_commands,
    observation,
    pointing_errors,
    quantise,
    read_encoders,
    reward,
    scored_errors,
    servo_errors,
    step_1,
    step_constants,
    step_info,
    terminated,
)
from dss14_env.envs.plant import block_views, step_block

SLOW = settings.get_profile("dss14-slow")  # tests/conftest.py

M_STATES, K_NOISE = 5, 4  # a small plant map of the right layout (the formulas do not care)
finite = st.floats(-1e3, 1e3, allow_nan=False)
small = st.floats(-1.0, 1.0, allow_nan=False)


@st.composite
def constants(draw) -> StepConstants:
    dt = draw(st.sampled_from([1e-3, 0.01, 0.02, 0.1]))
    scale = draw(st.floats(1e-4, 0.2))
    rl = draw(st.one_of(st.just(scale), st.floats(1e-4, 0.2)))  # rate_clip acts when scale > rl
    el_lo = draw(st.floats(0.0, 0.7))
    return StepConstants(dt, scale, rl, draw(st.floats(0.0, 0.05)), scale > rl,
                         draw(st.sampled_from([0.0, 2 * math.pi / 2**20, 2 * math.pi / 2**8])),
                         draw(st.sampled_from([0.0, 1e-6])), draw(st.floats(1e-3, 1e3)),
                         draw(st.floats(0.0, 10.0)), draw(st.floats(0.0, 1e4)),
                         (el_lo, el_lo + draw(st.floats(0.1, 0.8))), draw(st.floats(-1.0, 1.0)),
                         draw(st.floats(0.1, 4.0)), draw(st.booleans()))


@st.composite
def step_inputs(draw) -> dict:
    """Constants, a state, a plant map giving chosen outputs, a block row and an action."""
    k = draw(constants())
    s_az = draw(st.floats(k.az_centre - k.az_half_range, k.az_centre + k.az_half_range))
    s_el = draw(st.floats(*k.el_limits))
    theta = np.array([draw(st.floats(-0.1, 0.1)), draw(st.floats(-0.1, 0.1))])
    if k.quantum and draw(st.booleans()):  # land the absolute angle half a count between two
        n = draw(st.integers(-10**5, 10**5))
        theta[0] = k.quantum * (n + 0.5) - s_az
    c = theta + np.array([draw(st.floats(-1e-2, 1e-2)), draw(st.floats(-1e-2, 1e-2))])
    if draw(st.booleans()):  # far off: terminating, observation clamped
        c[1] += draw(st.sampled_from([-1.0, 1.0])) * draw(st.floats(0.01, 3.0))
    e_pick = abs(float((c[0] - theta[0]) * R2MD))
    me = draw(st.sampled_from([e_pick, math.nextafter(e_pick, 0.0), math.nextafter(e_pick, math.inf),
                               1e3, 1e5]))  # the bound exactly at the error, just below, above
    if draw(st.booleans()):  # elevation exactly at a travel limit
        el_lo = s_el + theta[1]
        k = StepConstants(**{**k.__dict__, "el_limits": (el_lo, el_lo + 0.5)})
    rates = st.floats(-k.rate_limit, k.rate_limit)
    rp = np.array([draw(rates), draw(rates)])
    actions = st.one_of(small, st.floats(-5.0, 5.0), st.sampled_from([-1.0, 1.0]))
    a = np.array([draw(actions), draw(actions)])
    if draw(st.booleans()):  # the rate command exactly at the acceleration bound
        a[0] = float(np.clip((rp[0] + k.rate_step) / k.action_scale, -1.0, 1.0))
    tiny = st.floats(-1e-6, 1e-6)
    noise = np.array([draw(tiny), draw(tiny)]) if k.encoder_sigma else np.zeros(2)
    point = np.array([draw(st.floats(-0.1, 0.1)), draw(st.floats(-0.1, 0.1))])
    cd = np.array([draw(small), draw(small)])
    return dict(k=k, start=np.array([s_az, s_el]), theta=theta, point=point, c=c, cd=cd, me=me, rp=rp,
                ap=np.array([draw(small), draw(small)]), em0=np.array([draw(finite), draw(finite)]),
                a=a.astype(np.float32 if draw(st.booleans()) else np.float64), noise=noise,
                xi=[draw(st.floats(-4.0, 4.0)) for _ in range(K_NOISE)],
                x0=[draw(small) for _ in range(M_STATES)],
                hits=(draw(st.integers(0, 5)), draw(st.integers(0, 5))), xel=draw(st.floats(0.1, 1.0)),
                wind=(draw(st.floats(0.0, 25.0)), draw(st.floats(-7.0, 7.0))))


def _run_both(d: dict) -> None:
    k, start, theta, c = d["k"], d["start"], d["theta"], d["c"]
    # a plant map whose outputs are the chosen encoder and pointing angles (constant column)
    h = 3 + K_NOISE
    rng = np.random.default_rng(0)
    M = np.zeros((M_STATES + 4, h + M_STATES))
    M[:M_STATES] = rng.normal(size=(M_STATES, h + M_STATES))
    M[M_STATES:, 2] = np.concatenate([theta, d["point"]])
    B = step_block(M, np.array(d["x0"]), np.zeros(4), 1)
    B[0, 3:h] = d["xi"]
    views = block_views(B, M_STATES)
    row = [*c, *(c * R2D), *d["cd"], *d["noise"]]
    sc = step_constants(k, tuple(start), d["me"], d["xel"], *d["wind"])
    st_in = ScalarState(*d["rp"].tolist(), *d["ap"].tolist(), *d["em0"].tolist(), *d["hits"], 3)
    a = d["a"]
    (obs1, rew1, term1, trunc1, info1), st1 = step_1(a, views[0], st_in, np.ascontiguousarray(M.T), row, sc)
    assert trunc1 is False

    # the plant map: one exact matrix product
    z_in = np.concatenate([(st1.r_az, st1.r_el), [1.0], d["xi"], d["x0"]])
    np.testing.assert_array_equal(B[1, M_STATES + h:], M[M_STATES:] @ z_in)
    np.testing.assert_allclose(B[1, h:h + M_STATES], M[:M_STATES] @ z_in, rtol=1e-12, atol=1e-12)
    # the batched pieces on the same inputs (N = 1)
    A = as_actions(a, (2,))[None]
    ac, r, rate_hit, acc_hit = limit_commands(A, d["rp"][None], k)
    assert (st1.a_az, st1.a_el) == tuple(ac[0]) and (st1.r_az, st1.r_el) == tuple(r[0])
    assert (info1["rate_limited"], info1["accel_limited"]) == (bool(rate_hit[0]), bool(acc_hit[0]))
    assert (info1["n_rate_limited"], info1["n_accel_limited"]) == (d["hits"][0] + rate_hit[0],
                                                                   d["hits"][1] + acc_hit[0])
    rel = read_encoders(theta[None], start[None], d["noise"][None], k)
    em, e = servo_errors(c[None], rel), servo_errors(c[None], theta[None])
    assert (st1.em_az, st1.em_el) == tuple(em[0])
    term = terminated(e, theta[None], start[None], np.array([d["me"]]), k)
    assert term1 == bool(term[0])
    pe = pointing_errors(c[None], d["point"][None], d["xel"])
    assert rew1 == reward(scored_errors(e, pe, k), ac, d["ap"][None], term, k)[0]
    clamp = bool(term[0]) or k.clamp_always(d["me"])
    obs = observation(em, d["em0"][None], (c * R2D)[None], d["cd"][None], rel, r, clamp, k)
    np.testing.assert_array_equal(obs1, obs[0])
    info = step_info(e, em, pe, np.array([d["wind"]]), A, r, rate_hit, acc_hit,
                     np.array([d["hits"]]) + np.stack([rate_hit, acc_hit], axis=1))
    assert list(info1) == list(info)
    for key, v in info.items():
        if key == "action_unclipped":
            assert info1[key] == tuple(v[0])
        else:
            assert info1[key] == v[0], key
    assert st1.j == 4
    assert (st1.n_rate, st1.n_acc) == (info1["n_rate_limited"], info1["n_accel_limited"])


@given(step_inputs())
def test_scalar_step_equals_the_batched_pieces(d: dict) -> None:
    _run_both(d)


@pytest.mark.slow
@SLOW
@given(step_inputs())
def test_scalar_step_equals_the_batched_pieces_many(d: dict) -> None:
    _run_both(d)


# ---------------------------------------------------------------------------- named edge cases
def _k(**kw) -> StepConstants:
    base = dict(dt=0.02, action_scale=0.01, rate_limit=0.005, rate_step=0.001, rate_clip=True, quantum=0.0,
                encoder_sigma=0.0, error_scale=10.0, action_change_weight=1.0, termination_penalty=1e4,
                el_limits=(0.1, 1.5), az_centre=0.0, az_half_range=4.6)
    return StepConstants(**{**base, **kw})


@pytest.mark.parametrize("a, r_prev, r, rate_hit, acc_hit", [
    ([2.0, -3.0], [0.0, 0.0], [0.001, -0.001], True, True),     # box clip, rate clip, acceleration
    ([0.4, 0.0], [0.0035, 0.0], [0.004, 0.0], False, False),   # exactly one rate step: no hit
    ([0.5, 0.0], [0.004, 0.0], [0.005, 0.0], False, False),    # exactly the rate limit: no hit
    ([0.5000001, 0.0], [0.0049, 0.0], [0.005, 0.0], True, False),
])
def test_limiter_edges(a, r_prev, r, rate_hit, acc_hit) -> None:
    k = _k()
    _, got, rh, ah = limit_commands(np.array([a]), np.array([r_prev]), k)
    np.testing.assert_allclose(got[0], r, rtol=1e-12)
    assert (bool(rh[0]), bool(ah[0])) == (rate_hit, acc_hit)


def test_quantiser_rounds_half_counts_up_and_reads_relative_to_the_start() -> None:
    q = 2.0 * math.pi / 2**20
    angles = np.array([[0.5 * q, -0.5 * q], [1.49 * q, -1.51 * q]])
    np.testing.assert_allclose(quantise(angles, q) / q, [[1.0, 0.0], [1.0, -2.0]])
    k = _k(quantum=q)
    start = np.array([[10.2 * q, 3.0 * q]])
    rel = read_encoders(np.array([[0.4 * q, 0.0]]), start, None, k)
    np.testing.assert_allclose(rel / q, [[0.8, 0.0]], atol=1e-9)  # 10.6 counts read as 11


@pytest.mark.parametrize("quantum", [0.0, 2 * math.pi / 2**20])
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_a_non_finite_plant_output_raises_floating_point_error(quantum: float, bad: float) -> None:
    """With quantised encoders too: the floor of NaN or inf must not surface as another error."""
    d = dict(k=_k(quantum=quantum), start=np.array([0.3, 0.8]), theta=np.array([bad, 0.0]), point=np.zeros(2),
             c=np.zeros(2), cd=np.zeros(2), me=1e3, rp=np.zeros(2), ap=np.zeros(2), em0=np.zeros(2),
             a=np.zeros(2), noise=np.zeros(2), xi=[0.0] * 4, x0=[0.0] * M_STATES, hits=(0, 0), xel=0.7,
             wind=(0.0, 0.0))
    with pytest.raises(FloatingPointError, match="the plant left the range it is meant for"):
        _run_both(d)


def test_termination_is_strictly_beyond_the_bounds() -> None:
    k = _k()
    me = 1000.0
    e = np.array([[me, -me], [math.nextafter(me, math.inf), 0.0]])
    theta = np.zeros((2, 2))
    start = np.array([[0.0, k.el_limits[0]], [0.0, 1.0]])
    assert terminated(e, theta, start, me, k).tolist() == [False, True]
    start_low = np.array([[0.0, math.nextafter(k.el_limits[0], 0.0)]])
    assert terminated(np.zeros((1, 2)), np.zeros((1, 2)), start_low, me, k).tolist() == [True]


def test_observation_clamps_errors_to_their_bounds_only_when_asked() -> None:
    k = _k()
    em = np.array([[2e5, -2e5]])
    out = observation(em, np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)),
                      np.zeros((1, 2)), True, k)
    assert out[0, 0] == OBS_ERROR_BOUND and out[0, 1] == -OBS_ERROR_BOUND and out[0, 2] == 1e6
    raw = observation(em, np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)),
                      np.zeros((1, 2)), False, k)
    assert raw[0, 0] == np.float32(2e4)


def test_pointing_error_is_command_less_pointing_angle() -> None:
    c = np.array([[0.01, 0.02]])
    point = np.array([[0.019, 0.006]])
    pe = pointing_errors(c, point, math.cos(math.radians(45.0)))
    cos_e = math.cos(math.radians(45.0))
    np.testing.assert_allclose(pe[0], [(0.02 - 0.019) * R2MD, (0.01 * cos_e - 0.006) * R2MD])


def test_scalar_step_refuses_what_the_batched_check_refuses() -> None:
    d = dict(k=_k(), start=np.zeros(2), theta=np.zeros(2), point=np.zeros(2), c=np.zeros(2), cd=np.zeros(2),
             me=1e3, rp=np.zeros(2), ap=np.zeros(2), em0=np.zeros(2), a=np.array([np.nan, 0.0]),
             noise=np.zeros(2), xi=[0.0] * 4, x0=[0.0] * M_STATES, hits=(0, 0), xel=0.7, wind=(0.0, 0.0))
    for bad in (np.array([np.nan, 0.0]), np.array([1e400, 0.0], np.longdouble), np.zeros(3), "ab", None):
        with pytest.raises(ValueError, match="^action must"):
            as_actions(bad, (2,))
        with pytest.raises(ValueError, match="^action must"):
            _run_both({**d, "a": bad})
