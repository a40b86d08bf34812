"""Mutated configuration files: every one either loads or fails with one ConfigError line that
names the file and a field (property-based: a key changed to a value of any type, removed, or
added; a documented leaf's unit or range broken).

Covers the documented files (``configs/model.yaml``, ``wind.yaml``, ``controllers.yaml``) and the
agents' training configurations (a sweep among them); ``configs/env.yaml`` has its own properties
(``tests/test_env_properties.py``).
"""

from __future__ import annotations

import copy
import os
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from dss14_env.agents.config import load_config as load_train_config
from dss14_env.agents.policy import check_resolved, shipped_policy
from dss14_env.agents.storage import PolicyFileError
from dss14_env.baselines.design import load_controllers_config
from dss14_env.core.schema import ConfigError, default_config_path, read_config
from dss14_env.model.assembly import build_model
from dss14_env.model.config import load_model_config
from dss14_env.wind.loads import load_wind_config


def _load_policy_config(path: Path) -> None:
    """What loading a policy folder reads of its ``config.yaml`` (no module imported)."""
    load_train_config(path)
    check_resolved(path)


#: the shipped files, and a shipped policy's ``config.yaml`` (a file that arrives with a folder)
FILES = {name: default_config_path(name) for name in
         ("model.yaml", "wind.yaml", "controllers.yaml", "ppo.yaml", "ppo_plain.yaml",
          "ppo_plain_sweep.yaml", "sac.yaml")}
FILES["policy/config.yaml"] = shipped_policy("ppo_plain") / "config.yaml"
LOADERS = {"model.yaml": load_model_config, "wind.yaml": load_wind_config,
           "controllers.yaml": load_controllers_config, "ppo.yaml": load_train_config,
           "ppo_plain.yaml": load_train_config, "ppo_plain_sweep.yaml": load_train_config,
           "sac.yaml": load_train_config, "policy/config.yaml": _load_policy_config}
#: strings a hostile file might hold: numbers in quotes, modules and gymnasium's module:id form
HOSTILE = ["1e-3", "256", "-1", "nan", "inf", "kg", "cm^3", "furlong", "random", "this", "os",
           "os:system", "payload_mod", "payload_mod:Evil-v0", "dss14_env.agents.residual",
           "DSS14-Plain-v0", "Pendulum-v1", "1e23", "1e300"]
scalars = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20),
                    st.booleans(), st.none(), st.text(max_size=8), st.sampled_from(HOSTILE))
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
    path = tmp_path / Path(name).name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    before = set(sys.modules)
    try:
        LOADERS[name](path)
    except ConfigError as exc:
        msg = str(exc)
        assert msg.startswith(str(path)), msg
        assert "\n" not in msg and ("field '" in msg or "section" in msg or "top level" in msg), msg
    except PolicyFileError as exc:  # a policy's config.yaml without what rebuilds its network
        assert str(exc).startswith(str(path)) and "field '" in str(exc)
    assert not {"this", "payload_mod"} & (set(sys.modules) - before)  # nothing imported


@pytest.mark.parametrize("name", sorted(LOADERS))
@settings(max_examples=100)
@given(data=st.data())
def test_mutated_file_loads_or_names_the_field(name: str, data, tmp_path_factory) -> None:
    raw, _ = read_config(FILES[name])  # the project's reading (1.29e6 a number)
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


# ------------------------------------------------------------------ command-line numbers
cli_numbers = st.one_of(st.integers(-10**6, 10**12), st.floats(allow_nan=True, allow_infinity=True),
                        st.sampled_from(["95", "90", "0", "-5", "1e3", "nan", "x", "", "50"]))


@settings(max_examples=60)
@given(steps=st.one_of(st.none(), st.integers(-5, 10**5)), threads=st.one_of(st.none(), cli_numbers),
       speeds=st.one_of(st.none(), st.lists(cli_numbers, max_size=3)),
       seeds=st.one_of(st.none(), st.lists(st.integers(-3, 2**70), max_size=3)))
def test_bench_numbers_plan_or_name_the_option(steps, threads, speeds, seeds) -> None:
    """Any --steps/--threads/--wind-speeds/--seeds: a plan within the environment's bounds, or
    one BenchOptionError naming the option.
    """
    from dss14_env.bench.plan import BenchOptionError, build_plan
    from dss14_env.envs.config import WIND_SPEED_MAX_KMH

    try:
        plan = build_plan(controllers=["pi_kp1"], steps=steps, threads=threads, seeds=seeds,
                          wind_speeds=None if speeds is None else [str(v) for v in speeds])
    except BenchOptionError as exc:
        assert str(exc).startswith("--") and "\n" not in str(exc)
        return
    assert all(0 < v <= WIND_SPEED_MAX_KMH for v in plan.wind_speeds_kmh)
    assert plan.threads is None or 1 <= plan.threads <= (os.cpu_count() or 1)
    assert all(r.steps * plan.dt > 1.0 for r in plan.runs.values())


@settings(max_examples=60)
@given(plants=cli_numbers, steps=cli_numbers, speeds=st.lists(cli_numbers, max_size=3),
       chunk=cli_numbers)
def test_campaign_numbers_spec_or_name_the_option(plants, steps, speeds, chunk) -> None:
    """Any campaign numbers: a spec within the environment's bounds, or one option error."""
    from dss14_env.bench import campaign as C
    from dss14_env.envs.config import WIND_SPEED_MAX_KMH

    try:
        kmh = C.parse_wind_speeds([str(v) for v in speeds], C.CampaignOptionError, hint="")
        spec = C.CampaignSpec(plants=plants, steps=steps, chunk_size=chunk, controllers=("pi_kp1",),
                              wind_speeds_kmh=kmh)
    except C.CampaignOptionError as exc:
        assert str(exc).startswith(("--", "warmup_s")) and "\n" not in str(exc)
        return
    assert all(0 < v <= WIND_SPEED_MAX_KMH for v in spec.wind_speeds_kmh)

