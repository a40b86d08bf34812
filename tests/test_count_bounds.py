"""Every count a command takes has a finite upper bound, refused in one line naming the option
before any work (a typo such as ``--episodes 100000000`` is an error, not gigabytes of memory),
and every number an environment takes has finite bounds.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from dss14_env import cli
from dss14_env.core.counts import MAX_SEEDS
from dss14_env.core.schema import ConfigError, field_spec
from dss14_env.core.seeds import parse_seed_list
from dss14_env.envs.config import EnvConfig, load_env_config


def _one_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


@pytest.mark.parametrize("argv, option", [
    (["bench", "--episodes", "100000000"], "--episodes"),
    (["bench", "--steps", "100000000000"], "--steps"),
    (["bench", "--seeds", "0-100000000000"], "--seeds"),
    (["bench", "--seeds", f"{2**64}"], "--seeds"),
    (["bench", "--sweep-seeds", "100000000"], "--sweep-seeds"),
    (["bench", "--sequential-episodes", "100000000"], "--sequential-episodes"),
    (["bench", "--threads", "100000"], "--threads"),
    (["campaign", "--plants", "100000000000"], "--plants"),
    (["campaign", "--steps", "100000000000"], "--steps"),
    (["campaign", "--chunk-size", "100000000000"], "--chunk-size"),
    (["campaign", "--first-plant", "100000000000000000000"], "--first-plant"),
    (["campaign", "--num-cpus", "100000"], "--num-cpus"),
    (["train", "ppo", "--config", "ppo_smoke", "--seeds", "0-100000000000"], "--seeds"),
])
def test_a_count_past_its_bound_is_one_line_before_work(tmp_path: Path, capsys, argv: list[str],
                                                       option: str) -> None:
    out = tmp_path / "out"
    assert cli.main([*argv, "--out", str(out)]) == 2
    _one_line(capsys, option)
    assert not out.exists()


def test_a_seed_range_is_measured_before_it_is_built() -> None:
    assert parse_seed_list([f"0-{MAX_SEEDS - 1}"])[-1] == MAX_SEEDS - 1
    with pytest.raises(ValueError, match=rf"^--seeds: at most {MAX_SEEDS} seeds"):
        parse_seed_list(["0-10", f"100-{MAX_SEEDS + 90}"])
    with pytest.raises(ValueError, match=rf"^--seeds: at most {MAX_SEEDS} seeds"):
        parse_seed_list([f"0-{10**12}"])


def test_every_number_of_the_environment_has_finite_bounds() -> None:
    for f in dataclasses.fields(EnvConfig):
        s = field_spec(f)
        if s is not None and s.kind in ("number", "integer", "pair", "list"):
            bounds = (s.lo, s.hi)
            assert None not in bounds and all(math.isfinite(b) for b in bounds), f.name


@pytest.mark.parametrize("key, value", [("wind_direction", 1e308), ("wind_direction", -1e10),
                                        ("step_time_s", 1e308), ("slew_time_s", 1e308)])
def test_environment_keywords_past_their_bounds_are_refused(key: str, value: float) -> None:
    with pytest.raises(ConfigError, match=rf"field '{key}': must be"):
        load_env_config(**{key: value})
