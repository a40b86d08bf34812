"""Every file the tools read, written by someone else: nothing it names is imported, its YAML is
read in one pass over its nodes with YAML 1.2 numbers, its arrays are measured before they are
read, and every refusal is one line naming the file.
"""

from __future__ import annotations

import shutil
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import yaml

from dss14_env.agents.campaign import check_saved_config
from dss14_env.agents.config import KNOWN_ENV_MODULES, load_config
from dss14_env.agents.policy import load_policy, shipped_policies, shipped_policy
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
