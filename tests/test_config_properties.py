"""Mutated configuration files: every one either loads or fails with one ConfigError line that
names the file and a field (property-based: a key changed to a value of any type, removed, or
added; a documented leaf's unit or range broken).

Covers the documented files (``configs/model.yaml``, ``wind.yaml``, ``controllers.yaml``) and the
agents' training configurations (a sweep among them); ``configs/env.yaml`` has its own properties
(``tests/test_env_properties.py``).
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from dss14_env.agents.config import load_config as load_train_config
from dss14_env.baselines.design import load_controllers_config
from dss14_env.core.schema import ConfigError, default_config_path, read_config
from dss14_env.model.assembly import build_model
from dss14_env.model.config import load_model_config
from dss14_env.wind.loads import load_wind_config

LOADERS = {"model.yaml": load_model_config, "wind.yaml": load_wind_config,
           "controllers.yaml": load_controllers_config, "ppo.yaml": load_train_config,
           "ppo_plain.yaml": load_train_config, "ppo_plain_sweep.yaml": load_train_config,
           "sac.yaml": load_train_config}
scalars = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20),
                    st.booleans(), st.none(), st.text(max_size=8),
                    st.sampled_from(["1e-3", "-1", "nan", "kg", "cm^3", "furlong", "random", "inf"]))
values = st.one_of(scalars, st.lists(scalars, max_size=3),
                   st.dictionaries(st.sampled_from(["value", "unit", "source", "range", "note", "x"]),
                                   scalars, max_size=4))


def _paths(tree, prefix=()):
    """Every key path of a nested mapping (leaves and sections)."""
    out = []
    if isinstance(tree, dict):
        for k, v in tree.items():
            out.append(prefix + (k,))
            out += _paths(v, prefix + (k,))
    return out


def _set(tree, path, value):
    node = tree
    for k in path[:-1]:
        node = node[k]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value


_DELETE = object()


def _check(name: str, data: dict, tmp_path: Path) -> None:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    try:
        LOADERS[name](path)
    except ConfigError as exc:
        msg = str(exc)
        assert msg.startswith(str(path)), msg
        assert "\n" not in msg and ("field '" in msg or "section" in msg or "top level" in msg), msg


@pytest.mark.parametrize("name", sorted(LOADERS))
@settings(max_examples=100)
@given(data=st.data())
def test_mutated_file_loads_or_names_the_field(name: str, data, tmp_path_factory) -> None:
    raw, _ = read_config(default_config_path(name))  # the project's reading (1.29e6 a number)
    tree = copy.deepcopy(raw)
    paths = _paths(tree)
    path = data.draw(st.sampled_from(paths))
    value = data.draw(st.one_of(values, st.just(_DELETE)))
    _set(tree, path, value)
    if data.draw(st.booleans()):
        tree[data.draw(st.sampled_from(["bogus", "n_env", "seeds", "loads"]))] = data.draw(scalars)
    _check(name, tree, tmp_path_factory.mktemp("cfg"))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(LOADERS))
@settings(settings.get_profile("dss14-slow"))
@given(data=st.data())
def test_mutated_file_loads_or_names_the_field_many(name: str, data, tmp_path_factory) -> None:
    test_mutated_file_loads_or_names_the_field.hypothesis.inner_test(name, data, tmp_path_factory)


def _model_file(tmp_path: Path, section: str, key: str, value) -> Path:
    raw, _ = read_config(default_config_path("model.yaml"))
    raw[section][key]["value"] = value
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def test_too_many_flexible_modes_names_the_field(tmp_path: Path) -> None:
    path = _model_file(tmp_path, "reduction", "n_flexible_modes", 500)
    with pytest.raises(ConfigError) as info:
        build_model(load_model_config(path))
    msg = str(info.value)
    assert msg.startswith(str(path)) and "field 'reduction.n_flexible_modes'" in msg and "148" in msg


def test_a_disconnected_structure_names_the_section(tmp_path: Path) -> None:
    path = _model_file(tmp_path, "structure", "k_quad", 1e-12)  # the quadripod floats free
    with pytest.raises(ConfigError) as info:
        build_model(load_model_config(path))
    msg = str(info.value)
    assert msg.startswith(str(path)) and "section 'structure'" in msg and "rigid-body modes" in msg
