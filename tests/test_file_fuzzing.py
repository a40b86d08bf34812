"""Property-based tests of the files the tools read: YAML (every configuration, a policy's
``config.yaml``, a campaign's), array files (``normalization.npz``, ``evaluations.npz``, replay
buffers) and a policy folder's statistics.

The invariant: the reader returns, or raises its one-line error naming the file
(:class:`~dss14_env.core.schema.ConfigError`, :class:`~dss14_env.core.arrays.ArrayFileError`,
:class:`~dss14_env.agents.storage.PolicyFileError`); never another exception, never a hang, and
what it returns holds only finite statistics.  About 100 examples per property by default.
"""

from __future__ import annotations

import io
import math
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from dss14_env.agents.config import load_config
from dss14_env.agents.policy import shipped_policy
from dss14_env.agents.storage import PolicyFileError, load_stats
from dss14_env.core.arrays import ArrayFileError, read_arrays
from dss14_env.core.schema import MAX_YAML_NODES, ConfigError, load_yaml

# ---------------------------------------------------------------------------- YAML
_TOKENS = ["a", "b", ": ", "- ", "[", "]", "{", "}", ", ", "\n", "  ", "&a ", "&b ", "*a", "*b", "1", "010",
           "1:30", "0x1f", "1e-3", ".inf", ".nan", "yes", "~", "'x'", '"y"', "!!python/object:os.system ",
           "!!binary ", "<<: *a", "? ", "#", "%YAML 1.1\n---\n", "---\n", "...\n", "\t", "\x00", "é"]
yaml_text = st.lists(st.sampled_from(_TOKENS), max_size=40).map("".join)


def _size(x: object) -> int:
    """Values in a loaded document (shared lists counted each time they appear)."""
    if isinstance(x, dict):
        return 1 + sum(_size(k) + _size(v) for k, v in x.items())
    if isinstance(x, list):
        return 1 + sum(_size(v) for v in x)
    return 1


@given(yaml_text)
@example("\x00")  # refused by PyYAML's reader, before the loader existed
@example("a: &a [*a]")
def test_any_yaml_text_loads_or_is_one_config_error(text: str) -> None:
    try:
        data = load_yaml(text, "fuzz.yaml")
    except ConfigError as exc:
        assert str(exc).startswith("fuzz.yaml: ") and "\n" not in str(exc)
        return
    assert _size(data) <= 2 * MAX_YAML_NODES  # keys and values: each within the node cap


@given(st.integers(1, 12), st.integers(2, 12))
def test_alias_chains_of_any_depth_and_width_are_measured(depth: int, width: int) -> None:
    lines = ["a0: &a0 [0]"] + [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * width) + "]"
                               for i in range(1, depth + 1)]
    text = "\n".join(lines) + "\n"
    try:
        load_yaml(text, "chain.yaml")
    except ConfigError as exc:
        assert "expands to more than" in str(exc)
        assert sum(width ** i for i in range(depth + 1)) > MAX_YAML_NODES // 2
    else:
        assert sum(width ** i for i in range(depth + 1)) <= 2 * MAX_YAML_NODES


plain_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(),
              st.text(max_size=5)),
    lambda kids: st.one_of(st.lists(kids, max_size=3),
                           st.dictionaries(st.text(max_size=4), kids, max_size=3)),
    max_leaves=8)
config_keys = st.sampled_from(["algo", "env_id", "env_kwargs", "env_module", "n_envs", "net_arch",
                               "total_timesteps", "learning_rate", "n_epochs", "seed", "eval_seeds",
                               "sweep", "batch_size", "n_steps", "bogus"])


@given(st.dictionaries(config_keys, plain_values, max_size=4))
def test_a_training_config_file_of_any_values_loads_or_is_one_config_error(tmp_path_factory, data) -> None:
    path = tmp_path_factory.mktemp("cfg") / "c.yaml"
    path.write_text(yaml.safe_dump({"env_id": "Pendulum-v1", **data}))
    try:
        cfg = load_config(path)
    except ConfigError as exc:
        assert str(exc).startswith(str(path)) and "\n" not in str(exc)
        return
    assert cfg.env_module is None


# ---------------------------------------------------------------------------- array files
def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


@given(st.binary(max_size=400), st.integers(0, 399), st.binary(min_size=1, max_size=8))
def test_any_bytes_read_as_arrays_or_one_error(tmp_path_factory, junk: bytes, at: int, patch: bytes) -> None:
    folder = tmp_path_factory.mktemp("npz")
    good = bytearray(_npz_bytes({"x": np.arange(4.0), "s": np.array("fp")}))
    good[at % len(good):at % len(good) + len(patch)] = patch  # a damaged copy of a good file
    for i, data in enumerate((junk, bytes(good))):
        path = folder / f"f{i}.npz"
        path.write_bytes(data)
        try:
            arrays = read_arrays(path, max_elements=1000, max_bytes=8000)
        except ArrayFileError as exc:
            assert str(exc).startswith(str(path)) and "\n" not in str(exc)
            continue
        assert sum(a.size for a in arrays.values()) <= 1000
        assert all(a.dtype != object for a in arrays.values())


stats_values = st.one_of(
    hnp.arrays(st.sampled_from([np.float64, np.float32, np.int64, np.bool_, np.complex128]),
               st.sampled_from([(), (1,), (2,), (12,), (3, 4)]),
               elements=None),
    st.sampled_from([np.nan, -np.inf, -1.0, 0.0, 1e-8, 10.0, 1e308]).map(np.asarray))


@pytest.fixture(scope="module")
def stats_folder(tmp_path_factory) -> tuple[Path, dict[str, np.ndarray]]:
    folder = tmp_path_factory.mktemp("stats")
    shutil.copy(shipped_policy("ppo_plain") / "normalization.npz", folder / "normalization.npz")
    with np.load(folder / "normalization.npz", allow_pickle=False) as d:
        return folder, {k: d[k] for k in d.files}


@given(st.dictionaries(st.sampled_from(["obs_mean", "obs_var", "obs_count", "clip_obs", "epsilon",
                                        "ret_mean", "ret_var", "ret_count", "clip_reward"]),
                       stats_values, min_size=1, max_size=3))
def test_statistics_of_any_values_load_finite_or_are_one_error(stats_folder, changes) -> None:
    folder, good = stats_folder
    path = folder / "fuzzed.npz"
    path.write_bytes(_npz_bytes({**good, **changes}))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a value cast with a warning (complex to real) fails
            _, stats = load_stats(path)
    except PolicyFileError as exc:
        assert str(exc).startswith(str(path)) and "\n" not in str(exc)
        return
    assert np.all(np.isfinite(stats.obs_mean)) and np.all(stats.obs_var >= 0)
    for v in (stats.clip_obs, stats.epsilon):
        assert math.isfinite(v) and v > 0
    assert math.isfinite(stats.obs_count) and stats.obs_count >= 0


@pytest.mark.parametrize("key", ["obs_mean", "obs_var", "ret_mean", "ret_var"])
def test_complex_statistics_are_refused_naming_the_field(stats_folder, key) -> None:
    folder, good = stats_folder
    path = folder / f"complex_{key}.npz"
    changed = {**good, key: np.asarray(good.get(key, good["obs_mean"]), np.complex128) + 1j}
    path.write_bytes(_npz_bytes(changed))
    with pytest.raises(PolicyFileError, match=rf"^{re.escape(str(path))}: field '{key}' must hold "
                                              r"finite real numbers$"):
        load_stats(path)
