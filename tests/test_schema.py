"""The one configuration layer (:mod:`dss14_env.core.schema`): specs, loader, error style."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from dss14_env.core.schema import (
    ConfigError,
    Spec,
    check_value,
    config_path,
    load_section,
    read_config,
    shipped_configs,
    spec,
)


@dataclasses.dataclass(frozen=True)
class Demo:
    dt: float = spec("s", lo=0.0, lo_open=True, hi=0.1, default=0.02)
    bits: int | None = spec("1", kind="integer", lo=8, hi=40, optional=True, default=20)
    speed: float | str = spec("km/h", lo=0.0, choices=("random",), default=50.0)
    grid: tuple = spec("km/h", kind="list", lo=0.0, default=(30.0, 50.0))
    limits: tuple = spec("deg", kind="pair", lo=0.0, hi=90.0, default=(6.0, 88.0))
    axes: str = spec(None, kind="str", choices=("az", "el", "both"), default="both")
    flag: bool = spec(None, kind="bool", default=False)
    extra: dict = spec(None, kind="mapping", default_factory=dict)


def test_defaults_and_scientific_notation(tmp_path) -> None:
    d = load_section(Demo, {"dt": 1e-3, "grid": [3e1, 70]}, "demo.yaml")
    assert d.dt == 0.001 and d.grid == (30.0, 70.0) and d.bits == 20
    path = tmp_path / "demo.yaml"  # scientific notation in a file is a number (YAML 1.2) ...
    path.write_text("dt: 1e-3\ngrid: [3e1, 7.0e1]\n")
    d = load_section(Demo, read_config(path)[0], str(path))
    assert d.dt == 0.001 and d.grid == (30.0, 70.0)
    with pytest.raises(ConfigError, match="field 'dt': .* got '1e-3'"):  # ... a string is not
        load_section(Demo, {"dt": "1e-3"}, "demo.yaml")


GOOD = [("bits", None), ("speed", "random"), ("speed", 0), ("limits", [0, 90]), ("flag", True),
        ("axes", "el"), ("extra", {"a": 1})]


@pytest.mark.parametrize("key,value", GOOD)
def test_good_values(key: str, value) -> None:
    d = load_section(Demo, {key: value}, "demo.yaml")
    got = getattr(d, key)
    assert got == (tuple(value) if isinstance(value, list) else value)


BAD = [("dt", 0.0, "> 0"), ("dt", 0.2, "<= 0.1"), ("dt", "fast", "a number"), ("dt", True, "a number"),
       ("dt", float("inf"), "a number"), ("bits", 20.5, "an integer"), ("bits", 4, ">= 8"),
       ("speed", "gusty", "'random'"), ("speed", -1, ">= 0"), ("grid", [], "a list"),
       ("grid", "30", "a list"), ("limits", [10, 5], "low <= high"), ("limits", [1, 2, 3], "pair"),
       ("axes", "x", "one of"), ("flag", "yes", "true or false"), ("extra", [1], "a mapping"),
       ("dt", None, "a number")]


@pytest.mark.parametrize("key,value,fragment", BAD)
def test_bad_values_name_file_and_field(key: str, value, fragment: str) -> None:
    with pytest.raises(ConfigError) as info:
        load_section(Demo, {key: value}, "demo.yaml")
    msg = str(info.value)
    assert msg.startswith(f"demo.yaml: field '{key}': must be"), msg
    assert fragment in msg and "\n" not in msg


def test_unknown_field_suggests_the_near_one() -> None:
    with pytest.raises(ConfigError, match=r"unknown field 'd_t' \(did you mean 'dt'\?\)"):
        load_section(Demo, {"d_t": 0.01}, "demo.yaml")


def test_required_fields_without_defaults() -> None:
    @dataclasses.dataclass(frozen=True)
    class Need:
        x: float = spec("m")

    with pytest.raises(ConfigError, match="field 'sec.x': is missing"):
        load_section(Need, {}, "f.yaml", "sec")


def test_yaml_syntax_error_is_a_config_error_with_position(tmp_path: Path) -> None:
    p = tmp_path / "bad.yaml"
    p.write_text("a: 1\nb: [1, 2\n")
    with pytest.raises(ConfigError) as info:
        read_config(p)
    msg = str(info.value)
    assert msg.startswith(f"{p}: not valid YAML (line") and "\n" not in msg


@pytest.mark.parametrize("text,key,line", [
    ("lr: 1.0e-4\ngamma: 0.99\nlr: 3.0e-4\n", "lr", 3),
    ("env_kwargs:\n  wind_speed_kmh: 30\n  wind_speed_kmh: 70\n", "wind_speed_kmh", 3),
    ("sweep: {lr: [1, 2], lr: [3]}\n", "lr", 1),
])
def test_a_repeated_key_is_refused_with_its_line(text: str, key: str, line: int, tmp_path: Path) -> None:
    path = tmp_path / "twice.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=rf"twice.yaml: not valid YAML \(line {line}, column \d+\): "
                                          rf"the key '{key}' appears twice"):
        read_config(path)
    # the same keys once each read as usual
    path.write_text("lr: 1.0e-4\ngamma: 0.99\nenv_kwargs: {wind_speed_kmh: 30}\n")
    assert read_config(path)[0] == {"lr": 1e-4, "gamma": 0.99, "env_kwargs": {"wind_speed_kmh": 30}}


def test_python_tags_are_not_built(tmp_path: Path) -> None:
    p = tmp_path / "evil.yaml"
    p.write_text("a: !!python/object/apply:os.system ['true']\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        read_config(p)


@pytest.mark.parametrize("name", ["ppo_plain", "ppo_plain.yaml", "configs/ppo_plain.yaml"])
def test_shipped_configs_by_name_from_anywhere(name: str, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # not the source tree
    assert config_path(name).name == "ppo_plain.yaml"
    assert config_path(name).is_file()


def test_a_path_wins_over_a_shipped_name(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "model.yaml").write_text("x: 1\n")
    assert config_path("model.yaml") == Path("model.yaml")


def test_unknown_name_lists_the_shipped_ones(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as info:
        config_path("ppo_plan")
    assert "ppo_plain" in str(info.value)
    assert set(shipped_configs()) >= {"model", "wind", "env", "controllers", "ppo", "ppo_plain"}


def test_spec_rejects_unknown_kind() -> None:
    with pytest.raises(ValueError):
        Spec(kind="complex")


def test_check_value_numpy_scalars_accepted() -> None:
    import numpy as np
    assert check_value(Spec("1", "integer", lo=0), np.int64(3), "w") == 3
    assert check_value(Spec("1", lo=0), np.float32(0.5), "w") == 0.5
