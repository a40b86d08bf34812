"""Every file the tools read, written by someone else: nothing it names is imported, its YAML is
read in one pass over its nodes with YAML 1.2 numbers, its arrays are measured before they are
read, and every refusal is one line naming the file.
"""

from __future__ import annotations

import io
import shutil
import sys
import types
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.lib import format as npy_format

from dss14_env.agents.campaign import check_saved_config, selected_evaluation
from dss14_env.agents.config import KNOWN_ENV_MODULES, load_config
from dss14_env.agents.policy import load_policy, shipped_policies, shipped_policy
from dss14_env.agents.storage import PolicyFileError, load_replay_buffer
from dss14_env.core.arrays import ArrayFileError, read_arrays
from dss14_env.core.schema import ConfigError, load_yaml, read_config


def _policy_copy(tmp_path: Path, name: str = "ppo_plain", **changes) -> Path:
    folder = tmp_path / "policy"
    shutil.copytree(shipped_policy(name), folder)
    if changes:
        cfg = yaml.safe_load((folder / "config.yaml").read_text())
        cfg.update(changes)
        (folder / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    return folder


# ------------------------------------------------------------------ nothing named is imported
@pytest.fixture
def package_payload(tmp_path: Path, monkeypatch) -> tuple[str, Path]:
    """A module inside this package's namespace that leaves a marker when imported: what a
    policy folder with a ``payload.py`` placed among the shipped policies would be.
    """
    marker = tmp_path / "marker"
    code = tmp_path / "downloaded"
    code.mkdir()
    (code / "payload.py").write_text(f"import pathlib\npathlib.Path({str(marker)!r}).write_text('ran')\n")
    pkg = f"dss14_env.agents.policies.downloaded_{tmp_path.name.replace('-', '_')}"
    module = types.ModuleType(pkg)
    module.__path__ = [str(code)]
    monkeypatch.setitem(sys.modules, pkg, module)
    return f"{pkg}.payload", marker


def test_a_module_under_the_package_named_by_a_policy_is_never_imported(package_payload,
                                                                       tmp_path: Path) -> None:
    name, marker = package_payload
    folder = _policy_copy(tmp_path, env_module=name)
    with pytest.raises(ConfigError, match=rf"config.yaml: field 'env_module': '{name}' names a module"):
        load_policy(folder)
    assert not marker.exists()


@pytest.mark.parametrize("name", ["dss14_env.agents.residualx", "dss14_env.agents.residual.x",
                                  "dss14_env.core", "dss14_env.", " dss14_env"])
def test_only_the_fixed_table_of_modules_may_be_named(tmp_path: Path, name: str) -> None:
    folder = _policy_copy(tmp_path, env_module=name)
    with pytest.raises(ConfigError, match="field 'env_module'"):
        load_config(folder / "config.yaml")


@pytest.mark.parametrize("policy", shipped_policies())
def test_every_shipped_policy_names_null_or_a_table_module(policy: str) -> None:
    cfg = load_config(shipped_policy(policy) / "config.yaml")
    assert cfg.env_module is None or cfg.env_module in KNOWN_ENV_MODULES


# ------------------------------------------------------------------ YAML: each node once
RECURSIVE = ["a: &a [*a]", "a: &a {x: *a}", "a: &a [1, [2, *a]]", "a: &a {x: [*a]}\nb: *a"]


@pytest.mark.parametrize("text", RECURSIVE)
def test_a_recursive_alias_is_refused_naming_the_file(tmp_path: Path, text: str) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(text + "\n")
    with pytest.raises(ConfigError, match=rf"^{path}: the YAML holds a value that contains itself"):
        read_config(path)


def test_a_recursive_alias_is_refused_by_every_yaml_reader(tmp_path: Path) -> None:
    """A policy folder's config.yaml (load_policy), --config (load_config), a campaign folder's
    config.yaml (--resume / --overwrite), each one line naming the file.
    """
    folder = _policy_copy(tmp_path)
    (folder / "config.yaml").write_text("algo: ppo\nnet_arch: &a [64, *a]\n")
    with pytest.raises(ConfigError, match=r"config.yaml: the YAML holds a value that contains itself"):
        load_policy(folder)
    with pytest.raises(ConfigError, match=r"config.yaml: the YAML holds a value that contains itself"):
        load_config(folder / "config.yaml")
    with pytest.raises(ValueError, match=r"--resume: .* no campaign to continue"):
        check_saved_config(load_config("ppo_plain"), folder)


def test_shared_aliases_are_measured_once_and_kept(tmp_path: Path) -> None:
    text = "a: &a [1, 2]\nb: [*a, *a, {x: *a}]\n"
    assert load_yaml(text, "s.yaml") == {"a": [1, 2], "b": [[1, 2], [1, 2], {"x": [1, 2]}]}


@pytest.mark.parametrize("text, value", [
    ("1:30", "1:30"), ("010", 10), ("0o10", 8), ("0x1f", 31), ("1_000", "1_000"), ("-7", -7),
    ("1e-3", 1e-3), ("1.29e6", 1.29e6), (".5", 0.5), ("1:30.5", "1:30.5"), ("+12", 12),
])
def test_numbers_are_yaml_1_2(text: str, value) -> None:
    got = load_yaml(f"x: {text}\n", "n.yaml")["x"]
    assert got == value and type(got) is type(value)


def test_a_yaml_1_1_sexagesimal_count_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text("env_id: Pendulum-v1\nn_epochs: 1:30\n")
    with pytest.raises(ConfigError, match=rf"^{path}: field 'n_epochs': must be an integer .* got '1:30'"):
        load_config(path)
    path.write_text("env_id: Pendulum-v1\nn_epochs: 010\n")
    assert load_config(path).n_epochs == 10


def test_the_shipped_configurations_read_as_before() -> None:
    """The shipped files hold no number that YAML 1.1 and 1.2 read differently (bar the
    scientific notation both readers here take as a number).
    """
    for path in sorted(Path(str(shipped_policy("ppo_plain"))).parents[1].glob("policies/*/config.yaml")):
        assert load_yaml(path.read_text(), str(path)) == yaml.safe_load(path.read_text())
    assert np.isfinite(read_config("model")[0]["hydraulics"]["beta"]["value"])


# ------------------------------------------------------------------ arrays measured before read
def _npy_header(shape: tuple[int, ...], dtype: str = "<f8") -> bytes:
    buf = io.BytesIO()
    npy_format.write_array_header_1_0(buf, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buf.getvalue()


@pytest.fixture
def no_data_read(monkeypatch) -> None:
    """Any read of array data fails the test: a refusal must come from the headers alone."""
    def refused(*_: object, **__: object) -> None:
        raise AssertionError("array data was read before the headers were measured")

    monkeypatch.setattr(np, "load", refused)


def test_a_compressed_statistics_bomb_is_refused_from_its_headers(tmp_path: Path, no_data_read) -> None:
    folder = _policy_copy(tmp_path)
    stats = folder / "normalization.npz"
    with zipfile.ZipFile(stats, "w", zipfile.ZIP_DEFLATED) as zf:
        with zf.open("obs_mean.npy", "w") as fh:
            fh.write(_npy_header((4 << 20,)))
            fh.write(bytes(8 << 20) * 4)
    assert stats.stat().st_size < 200_000  # 32 MiB of zeros in a small file
    with pytest.raises(PolicyFileError, match=rf"^{stats}: its headers claim 4194304 elements"):
        load_policy(folder)


@pytest.mark.parametrize("suffix", [".npz", ".npy"])
def test_a_header_claiming_93_gib_is_one_line(tmp_path: Path, suffix: str, no_data_read) -> None:
    path = tmp_path / f"huge{suffix}"
    if suffix == ".npy":
        path.write_bytes(_npy_header((12_500_000_000,)))
    else:
        with zipfile.ZipFile(path, "w") as zf:
            zf.writestr("obs_mean.npy", _npy_header((12_500_000_000,)))
    with pytest.raises(ArrayFileError, match=rf"^{path}: its headers claim 12500000000 elements "
                                             rf"\(100000000000 bytes\)"):
        read_arrays(path)


def test_statistics_and_evaluations_read_as_written(tmp_path: Path) -> None:
    a = {"x": np.arange(5.0), "n": np.int64(3), "s": np.array("text")}
    np.savez(tmp_path / "a.npz", **a)
    got = read_arrays(tmp_path / "a.npz")
    assert set(got) == set(a) and all(np.array_equal(got[k], a[k]) for k in a)
    np.save(tmp_path / "b.npy", np.eye(3))
    assert np.array_equal(read_arrays(tmp_path / "b.npy")[""], np.eye(3))
    with pytest.raises(ArrayFileError, match=rf"^{tmp_path / 'a.npz'}: its headers claim 7 elements"):
        read_arrays(tmp_path / "a.npz", max_elements=6)
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(ArrayFileError, match=r"bad.npz: not a readable array file"):
        read_arrays(tmp_path / "bad.npz")


def test_an_evaluation_history_bomb_is_refused(tmp_path: Path, no_data_read) -> None:
    path = tmp_path / "evaluations.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("selection_score.npy", _npy_header((375_000_000,)))
    with pytest.raises(ArrayFileError, match=rf"^{path}: its headers claim 375000000 elements"):
        selected_evaluation(path)


def test_a_replay_buffer_larger_than_the_buffer_is_refused_from_its_headers(tmp_path: Path,
                                                                           no_data_read) -> None:
    buffer = types.SimpleNamespace(buffer_size=4, observations=np.zeros((4, 1, 3), np.float32),
                                   actions=np.zeros((4, 1, 2), np.float32), pos=0, full=False)
    path = tmp_path / "replay_buffer.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("observations.npy", _npy_header((1000, 1, 3), "<f4"))
    with pytest.raises(PolicyFileError, match=rf"^{path}: its headers claim 3000 elements"):
        load_replay_buffer(path, buffer)


# ------------------------------------------------------------------ policies that score nothing
def _edit_stats(folder: Path, **changes) -> None:
    with np.load(folder / "normalization.npz", allow_pickle=False) as d:
        a = {k: d[k] for k in d.files}
    a.update({k: np.asarray(v) for k, v in changes.items()})
    np.savez(folder / "normalization.npz", **a)


@pytest.mark.parametrize("changes, field", [
    ({"clip_obs": np.nan}, "clip_obs"), ({"epsilon": -1e-8}, "epsilon"), ({"epsilon": np.inf}, "epsilon"),
    ({"clip_obs": [1.0, 2.0]}, "clip_obs"), ({"obs_count": -1.0}, "obs_count"),
])
def test_statistics_that_make_every_observation_nan_are_refused(tmp_path: Path, changes, field) -> None:
    folder = _policy_copy(tmp_path)
    _edit_stats(folder, **changes)
    with pytest.raises(PolicyFileError, match=rf"normalization.npz: field '{field}' must be one finite"):
        load_policy(folder)


def test_nan_weights_are_refused_at_load(tmp_path: Path) -> None:
    import torch

    folder = _policy_copy(tmp_path)
    data = torch.load(folder / "policy.pt", weights_only=True)
    name = next(k for k, v in data["state_dict"].items() if v.is_floating_point())
    data["state_dict"][name][0] = float("nan")
    torch.save(data, folder / "policy.pt")
    with pytest.raises(PolicyFileError, match=rf"policy.pt: weight '{name}' holds NaN"):
        load_policy(folder)
