"""Property-based tests of the environments' inputs: actions of any dtype, shape and value, seeds,
reset options, keyword arguments and mutations of ``configs/env.yaml``.

The invariant, for the single and the vector environment alike: either a ``ValueError`` naming
the input (``action must ...``, ``seed must ...``, ``<source>: field '<key>': ...``) raised
before anything changes, or finite observations and rewards with boolean ``terminated`` /
``truncated`` flags.  About 100 examples per property by default; ``HYPOTHESIS_PROFILE=dss14-slow``
or the ``slow`` tests run 1,000+.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re

import numpy as np
import pytest
import yaml
from hypothesis import event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from dss14_env.core.schema import default_config_path, field_spec
from dss14_env.envs.config import EPISODE_KEYS, EnvConfig, load_env_config
from dss14_env.envs.core import as_actions, check_seed
from dss14_env.envs.env import DSS14Env
from dss14_env.envs.vector import DSS14VectorEnv

SLOW = settings.get_profile("dss14-slow")  # tests/conftest.py

KEYS = [f.name for f in dataclasses.fields(EnvConfig)]
# a few plants serve all examples (wind speed, dt and parameters pick the plant)
BASE = dict(scenario="hold", wind_speed_kmh=50.0, wind_direction="front")

# ---------------------------------------------------------------------------- value strategies
numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30),
                    st.sampled_from([0, 1, -1, 0.5, 1e-300, 1e300, 1e5, 90.0, 90.000001, -0.0]))
scalars = st.one_of(numbers, st.booleans(), st.none(), st.text(max_size=6),
                    st.sampled_from(["random", "front", "side", "1e-2", "50", "nan", "hold", "both"]))
values = st.one_of(scalars, st.lists(scalars, max_size=3),
                   st.dictionaries(st.text(max_size=4), scalars, max_size=2))
# values that keep the plant cache small where a key picks the plant
PLANT_KEYS = {"dt": st.sampled_from([0.02, 0.01, 0.0, -0.02, 0.5, 1e-300, float("nan"), "1e-2", None]),
              "wind_speed_kmh": st.sampled_from([0.0, 30.0, 89.9, 90.0, 90.01, 3000.0, 1e5, -1.0, "random",
                                                 "50"]),
              "wind_speed_grid_kmh": st.sampled_from([[30.0], [0.0, 70.0], [], [1e5], ["x"]]),
              "params": st.sampled_from([None, {}, {"hydraulics.zeta_o": 0.7}, {"hydraulics.zeta_o": 5.0},
                                         {"x": 1.0}, {"hydraulics.mu": "1e9"}, [1]])}


def _in_spec(key: str) -> st.SearchStrategy:
    """Values that the key's spec allows, and values just beyond its bounds."""
    spec = field_spec(next(f for f in dataclasses.fields(EnvConfig) if f.name == key))
    lo = spec.lo if spec.lo is not None else -1e3
    hi = spec.hi if spec.hi is not None else 1e3
    inside = st.floats(lo, hi, exclude_min=spec.lo_open, exclude_max=spec.hi_open)
    edges = st.sampled_from([lo, hi, math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf)])
    if spec.kind == "bool":
        return st.booleans()
    if spec.kind == "str":
        return st.sampled_from(spec.choices)
    if spec.kind == "integer":
        return st.integers(int(lo) - 1, int(hi) + 1)
    if spec.kind == "pair":
        return st.tuples(inside, inside).map(sorted)
    if spec.kind == "list":
        return st.lists(st.one_of(inside, edges), min_size=1, max_size=3)
    if spec.kind == "mapping":
        return st.none()
    out = st.one_of(inside, edges)
    return st.one_of(out, st.sampled_from(spec.choices)) if spec.choices else out


def value_for(key: str) -> st.SearchStrategy:
    if key in PLANT_KEYS:
        return PLANT_KEYS[key]
    if key not in KEYS:
        return values
    spec = _in_spec(key)
    return st.one_of(spec, spec, spec, spec, values)


def _names(exc: BaseException, *names: str) -> bool:
    text = str(exc)
    return any(n in text for n in names)


def _finite_steps(env, n: int, rng: np.random.Generator) -> None:
    """A few steps with random actions: finite observations and rewards, boolean flags."""
    vector = isinstance(env, DSS14VectorEnv)
    shape = (env.num_envs, 2) if vector else (2,)
    for _ in range(n):
        obs, rew, term, trunc, info = env.step(rng.uniform(-1.5, 1.5, shape))
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(rew))
        assert env.observation_space.contains(obs)
        if vector:
            assert term.dtype == bool and trunc.dtype == bool and term.shape == trunc.shape == (env.num_envs,)
        else:
            assert type(term) is bool and trunc is False
        for key in ("servo_error_az_mdeg", "pointing_error_xel_mdeg", "measured_error_el_mdeg"):
            assert np.all(np.isfinite(info[key]))


def _same_future(a, b) -> None:
    """Two environments continue identically (the failed call changed nothing)."""
    shape = (a.num_envs, 2) if isinstance(a, DSS14VectorEnv) else (2,)
    for x in np.random.default_rng(9).uniform(-1, 1, (3,) + shape):
        oa, ra, *_ = a.step(x)
        ob, rb, *_ = b.step(x)
        np.testing.assert_array_equal(oa, ob)
        np.testing.assert_array_equal(ra, rb)


# ---------------------------------------------------------------------------- actions
DTYPES = [np.bool_, np.int8, np.int64, np.uint64, np.float16, np.float32, np.float64, np.longdouble,
          np.complex128, np.str_, np.object_]
SHAPES = [(2,), (), (1,), (3,), (2, 1), (1, 2), (0,)]


@st.composite
def any_action(draw, n: int | None = None):
    shapes = SHAPES if n is None else [(n, 2), (2,), (n, 3), (n,), (n + 1, 2)]
    kind = draw(st.integers(0, 3))
    if kind == 0:  # numpy arrays of any dtype and shape
        dtype = draw(st.sampled_from(DTYPES))
        shape = draw(st.sampled_from(shapes))
        size = int(np.prod(shape))
        if dtype is np.object_:
            items = draw(st.lists(scalars, min_size=size, max_size=size))
            return np.array(items, dtype=object).reshape(shape)
        if dtype is np.str_:
            texts = st.sampled_from(["0.5", "1e3", "a", ""])
            return np.array(draw(st.lists(texts, min_size=size, max_size=size))).reshape(shape)
        return draw(hnp.arrays(dtype, shape))
    if kind == 1:  # nested Python lists of anything
        items = st.one_of(numbers, st.lists(numbers, max_size=3), st.text(max_size=2))
        return draw(st.lists(items, max_size=4))
    if kind == 2:  # well-formed float actions
        return draw(hnp.arrays(draw(st.sampled_from([np.float32, np.float64])), shapes[0],
                               elements=st.floats(-3, 3, width=32)))
    return draw(st.one_of(numbers, st.none(), st.text(max_size=3)))


@pytest.fixture(scope="module")
def single() -> DSS14Env:
    env = DSS14Env(**BASE, encoder_noise_mdeg=0.05)
    env.reset(seed=0)
    return env


def _check_single_action(env: DSS14Env, action) -> None:
    try:
        expected = as_actions(action, (2,))
    except ValueError as exc:
        expected = exc
    before = copy.deepcopy(env)
    try:
        obs, rew, term, trunc, info = env.step(action)
    except ValueError as exc:
        assert isinstance(expected, ValueError) and str(exc).startswith("action must")
        _same_future(env, before)
        return
    assert not isinstance(expected, ValueError), f"accepted {action!r}"
    assert info["action_unclipped"] == tuple(expected.tolist())
    assert np.all(np.isfinite(obs)) and np.isfinite(rew) and type(term) is bool and trunc is False
    if term:
        env.reset(seed=1)


@given(any_action())
def test_single_env_actions_of_any_kind(single: DSS14Env, action) -> None:
    _check_single_action(single, action)


@pytest.mark.slow
@SLOW
@given(any_action())
def test_single_env_actions_of_any_kind_many(single: DSS14Env, action) -> None:
    _check_single_action(single, action)


@pytest.fixture(scope="module")
def vector() -> DSS14VectorEnv:
    venv = DSS14VectorEnv(num_envs=3, max_episode_steps=50, **BASE)
    venv.reset(seed=0)
    return venv


def _check_vector_action(venv: DSS14VectorEnv, action) -> None:
    try:
        expected = as_actions(action, (3, 2))
    except ValueError as exc:
        expected = exc
    before = copy.deepcopy(venv)
    try:
        obs, rew, term, trunc, info = venv.step(action)
    except ValueError as exc:
        assert isinstance(expected, ValueError) and str(exc).startswith("action must")
        _same_future(venv, before)
        return
    assert not isinstance(expected, ValueError), f"accepted {action!r}"
    np.testing.assert_array_equal(info["action_unclipped"], expected)
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(rew))
    assert term.dtype == bool and trunc.dtype == bool


@given(any_action(n=3))
def test_vector_env_actions_of_any_kind(vector: DSS14VectorEnv, action) -> None:
    _check_vector_action(vector, action)


@pytest.mark.slow
@SLOW
@given(any_action(n=3))
def test_vector_env_actions_of_any_kind_many(vector: DSS14VectorEnv, action) -> None:
    _check_vector_action(vector, action)


@pytest.mark.parametrize("action", [np.array(["0.5", "1e3"]), np.array([0.5 + 1j, 0.0]), [10**400, 0],
                                    [[0.1], [0.2]], np.array([True, False]), "0.5 0.5"])
def test_both_envs_refuse_the_same_actions_with_one_message(single: DSS14Env, vector: DSS14VectorEnv,
                                                           action) -> None:
    with pytest.raises(ValueError, match="^action must be an array of real numbers|^action must have shape"):
        single.step(action)
    batch = np.array([action] * 3, dtype=object) if not isinstance(action, str) else action
    with pytest.raises(ValueError, match="^action must be an array of real numbers|^action must have shape"):
        vector.step(batch)


# ---------------------------------------------------------------------------- seeds
seeds = st.one_of(st.none(), st.integers(-5, 2**70), st.booleans(), st.floats(), st.text(max_size=3),
                  st.sampled_from([np.int64(3), np.uint8(7), np.int32(-1), np.float64(1.0)]),
                  st.lists(st.one_of(st.none(), st.integers(-2, 10)), max_size=4))


def _seed_ok(seed) -> bool:
    try:
        check_seed(seed)
    except ValueError:
        return False
    return True


@given(seeds)
def test_seeds_are_checked_alike(seed) -> None:
    env = DSS14Env(**BASE)
    try:
        env.reset(seed=seed)
    except ValueError as exc:
        assert not _seed_ok(seed) and str(exc).startswith("seed must")
    else:
        assert _seed_ok(seed)
    venv = DSS14VectorEnv(num_envs=2, **BASE)
    ok = (len(seed) == 2 and all(_seed_ok(x) for x in seed)) if isinstance(seed, list) else _seed_ok(seed)
    try:
        venv.reset(seed=seed)
    except ValueError as exc:
        assert not ok and str(exc).startswith("seed must")
    else:
        assert ok


def test_numpy_integer_seeds_give_the_same_episodes_as_python_ints() -> None:
    a, b = DSS14Env(), DSS14Env()
    assert np.array_equal(a.reset(seed=np.int64(4))[0], b.reset(seed=4)[0])
    va, vb = DSS14VectorEnv(num_envs=2), DSS14VectorEnv(num_envs=2)
    assert np.array_equal(va.reset(seed=np.int64(4))[0], vb.reset(seed=4)[0])


# ---------------------------------------------------------------------------- reset options
@st.composite
def options(draw) -> dict:
    keys = draw(st.lists(st.sampled_from(sorted(EPISODE_KEYS) * 10 + ["dt", "foo"]), max_size=2, unique=True))
    return {k: draw(value_for(k)) for k in keys}


def _check_options(opts: dict) -> None:
    env = DSS14Env(**BASE)
    env.reset(seed=0)
    before = copy.deepcopy(env)
    try:
        env.reset(seed=1, options=opts)
    except ValueError as exc:
        assert _names(exc, *map(str, opts)), f"{exc} names none of {list(opts)}"
        _same_future(env, before)
        event("refused")
        return
    event("accepted")
    _finite_steps(env, 3, np.random.default_rng(0))


@given(options())
def test_reset_options_of_any_kind(opts: dict) -> None:
    _check_options(opts)


@pytest.mark.slow
@SLOW
@given(options())
def test_reset_options_of_any_kind_many(opts: dict) -> None:
    _check_options(opts)


# ---------------------------------------------------------------------------- keyword arguments
@st.composite
def kwargs(draw) -> dict:
    keys = draw(st.lists(st.sampled_from(KEYS * 10 + ["wind_speed_mph", "Dt"]), min_size=1, max_size=2,
                         unique=True))
    return {k: draw(value_for(k)) for k in keys}


def _check_kwargs(kw: dict, vector_env: bool) -> None:
    kw = {**BASE, **kw}
    try:
        env = DSS14VectorEnv(num_envs=2, max_episode_steps=20, **kw) if vector_env else DSS14Env(**kw)
        env.reset(seed=0)
    except ValueError as exc:
        assert _names(exc, *kw), f"{exc} names none of {list(kw)}"
        event("refused")
        return
    event("accepted")
    _finite_steps(env, 3, np.random.default_rng(1))


@given(kwargs(), st.booleans())
def test_keyword_arguments_of_any_kind(kw: dict, vector_env: bool) -> None:
    _check_kwargs(kw, vector_env)


@pytest.mark.slow
@SLOW
@given(kwargs(), st.booleans())
def test_keyword_arguments_of_any_kind_many(kw: dict, vector_env: bool) -> None:
    _check_kwargs(kw, vector_env)


# ---------------------------------------------------------------------------- configs/env.yaml mutations
SHIPPED = default_config_path("env.yaml").read_text()
KEY_LINES = [m.group(1) for m in re.finditer(r"^(\w+):", SHIPPED, re.M)]


@st.composite
def mutated_config(draw) -> tuple[str, str]:
    """``(yaml text, what was mutated)``: a key changed to a random value of a random type, removed,
    duplicated, an unknown key added, or the YAML broken."""
    key = draw(st.sampled_from(KEY_LINES))
    how = draw(st.sampled_from(["change", "remove", "duplicate", "unknown", "break"]))
    lines = SHIPPED.splitlines()
    i = next(n for n, line in enumerate(lines) if line.startswith(f"{key}:"))
    if how == "change":
        lines[i] = f"{key}: {yaml.safe_dump(draw(value_for(key)), default_flow_style=True).strip()}"
        if lines[i].endswith("..."):
            lines[i] = lines[i][:-3].rstrip()
    elif how == "remove":
        del lines[i]
    elif how == "duplicate":
        lines.insert(i + 1, f"{key}: {yaml.safe_dump(draw(value_for(key)), default_flow_style=True).strip()}")
        if lines[i + 1].endswith("..."):
            lines[i + 1] = lines[i + 1][:-3].rstrip()
    elif how == "unknown":
        lines.insert(i, "wind_gust_factor: 2.0")
        key = "wind_gust_factor"
    else:
        lines[i] = f"{key}: [1, 2"
    return "\n".join(lines) + "\n", key


def _check_config(tmp_path, text: str, key: str, vector_env: bool) -> None:
    path = tmp_path / "env.yaml"
    path.write_text(text)
    try:
        env = (DSS14VectorEnv(num_envs=2, max_episode_steps=20, config=path, **BASE) if vector_env
               else DSS14Env(config=path, **BASE))
        env.reset(seed=0)
    except ValueError as exc:
        assert str(path) in str(exc) or "keyword arguments" in str(exc), str(exc)
        assert _names(exc, key, "not valid YAML"), f"{exc} does not name {key}"
        event("refused")
        return
    event("accepted")
    _finite_steps(env, 3, np.random.default_rng(2))


@given(mutated_config(), st.booleans())
def test_mutated_configuration_files(tmp_path, mutation: tuple[str, str], vector_env: bool) -> None:
    _check_config(tmp_path, *mutation, vector_env)


@pytest.mark.slow
@SLOW
@given(mutated_config(), st.booleans())
def test_mutated_configuration_files_many(tmp_path, mutation: tuple[str, str], vector_env: bool) -> None:
    _check_config(tmp_path, *mutation, vector_env)


def test_the_shipped_configuration_loads_strictly() -> None:
    # every key of configs/env.yaml is present and valid on its own (no defaults needed)
    from dss14_env.core.schema import load_section, read_config

    data, source = read_config("env")
    cfg = load_section(EnvConfig, data, source, defaults=False).checked(source)
    assert cfg == load_env_config()
