"""What a process keeps after loading a file: the parsed configuration texts
(:func:`dss14_env.core.schema.parsed_config`) give the same values as a fresh parse, never a
stale file's and never another caller's changes.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from dss14_env.core.schema import config_path, load_yaml, parsed_config, read_config
from dss14_env.envs.config import load_env_config
from dss14_env.model.config import load_model_config


@pytest.mark.parametrize("name", ["model", "env", "controllers", "ppo"])
def test_read_config_equals_a_fresh_parse(name: str) -> None:
    path = config_path(name)
    fresh = load_yaml(path.read_text(encoding="utf-8"), str(path))
    first, _ = read_config(name)
    again, _ = read_config(name)  # from the parsed text
    assert first == fresh and again == fresh


def test_loaders_give_equal_objects_with_and_without_the_parsed_texts() -> None:
    parsed_config.cache_clear()
    model, env = load_model_config(), load_env_config()
    assert parsed_config.cache_info().currsize >= 1
    assert load_model_config() == model and load_env_config() == env
    parsed_config.cache_clear()
    assert load_model_config() == model and load_env_config() == env


def test_a_callers_changes_reach_no_other_caller() -> None:
    data, _ = read_config("model")
    data["board"]["changed"] = 1
    data.pop("structure")
    again, _ = read_config("model")
    assert "changed" not in again["board"] and "structure" in again


def _write(path: Path, text: str, mtime_ns: int) -> None:
    path.write_text(text, encoding="utf-8")
    os.utime(path, ns=(mtime_ns, mtime_ns))


def test_an_edited_file_is_read_anew(tmp_path: Path) -> None:
    f = tmp_path / "env_edit.yaml"
    # same size and the same modification time: only the content tells them apart
    _write(f, "wind_speed_kmh: 30.0\n", 1_000_000_000)
    assert read_config(f)[0] == {"wind_speed_kmh": 30.0}
    assert load_env_config(f).wind_speed_kmh == 30.0
    _write(f, "wind_speed_kmh: 40.0\n", 1_000_000_000)
    assert read_config(f)[0] == {"wind_speed_kmh": 40.0}
    assert load_env_config(f).wind_speed_kmh == 40.0


def test_a_broken_edit_is_refused_not_served_from_the_earlier_text(tmp_path: Path) -> None:
    f = tmp_path / "env_broken.yaml"
    _write(f, "wind_speed_kmh: 30.0\n", 1_000_000_000)
    read_config(f)
    _write(f, "wind_speed_kmh: [30.0\n", 1_000_000_000)
    with pytest.raises(ValueError, match="not valid YAML"):
        read_config(f)


def test_the_parsed_texts_are_capped() -> None:
    assert parsed_config.cache_info().maxsize is not None
