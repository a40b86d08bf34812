"""The configuration layer: one schema mechanism and one loader for every YAML file.

Each parameter in a documented YAML file is a mapping ``{value, unit, source[, range][, note]}``
in the source's own units; :func:`param` converts it to SI (:mod:`dss14_env.core.units`) and
checks it (finite, sign, range, unit family).  A wrong or missing value raises
:class:`ConfigError` naming the file and the field.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

import yaml

from dss14_env.core.units import AXES, UNITS, si_unit, to_si


class ConfigError(ValueError):
    """A configuration value is missing, malformed or out of range."""


@dataclass(frozen=True)
class Param:
    """One parameter as read from the file, converted to SI."""

    name: str
    value: Any  # float, or tuple of floats for vector parameters
    unit: str  # SI unit
    source: str
    range: tuple[float, float] | None = None
    note: str = ""


def spec(unit: str, *, axis: bool = False, vector: bool = False, integer: bool = False,
          positive: bool = True, nonzero: bool = True) -> Any:
    return field(metadata=dict(unit=unit, axis=axis, vector=vector, integer=integer,
                               positive=positive, nonzero=nonzero))


def default_config_path(name: str = "model.yaml") -> Path:
    """Path of a configuration file shipped in the ``configs`` package."""
    return Path(str(resources.files("dss14_env.configs").joinpath(name)))


def read_yaml(path: Path) -> Mapping[str, Any]:
    if not path.is_file():
        raise ConfigError(f"configuration file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from exc
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: top level must be a mapping")
    return data


def param(raw: Any, name: str, meta: Mapping[str, Any], path: Path) -> Param:
    where = f"{path}: field '{name}'"
    if not isinstance(raw, Mapping) or "value" not in raw:
        raise ConfigError(f"{where}: expected a mapping with 'value', 'unit' and 'source'")
    for key in ("unit", "source"):
        if key not in raw:
            raise ConfigError(f"{where}: missing '{key}'")
    unit = raw["unit"]
    if unit not in UNITS:
        raise ConfigError(f"{where}: unknown unit {unit!r}")
    if si_unit(unit) != meta["unit"]:
        raise ConfigError(f"{where}: unit {unit!r} is not a {meta['unit']} quantity")
    value = raw["value"]

    def check(v: Any) -> float:
        if isinstance(v, str):  # PyYAML reads 1.29e6 (no dot-sign) as a string
            try:
                v = float(v)
            except ValueError:
                raise ConfigError(f"{where}: value {v!r} is not a number") from None
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{where}: value {v!r} is not a number")
        if meta["integer"] and (not float(v).is_integer() or v < 1):
            raise ConfigError(f"{where}: value {v!r} must be a positive integer")
        if not math.isfinite(v):
            raise ConfigError(f"{where}: value {v!r} is not finite")
        if meta["positive"] and v < 0 or meta["nonzero"] and v == 0:
            raise ConfigError(f"{where}: value {v!r} must be positive")
        return int(v) if meta["integer"] else to_si(v, unit)

    if meta["vector"]:
        if not isinstance(value, list) or not value:
            raise ConfigError(f"{where}: value must be a non-empty list")
        si: Any = tuple(check(v) for v in value)
    else:
        si = check(value)
    rng = raw.get("range")
    rng_si = None
    if rng is not None:
        if not (isinstance(rng, list) and len(rng) == 2):
            raise ConfigError(f"{where}: range must be [low, high]")
        lo, hi = (check(v) for v in rng)
        if lo > hi:
            raise ConfigError(f"{where}: range low {rng[0]} > high {rng[1]}")
        rel = 1e-9 * max(abs(lo), abs(hi))
        if not all(lo - rel <= v <= hi + rel for v in (si if meta["vector"] else (si,))):
            raise ConfigError(f"{where}: value {value} outside its range {rng}")
        rng_si = (lo, hi)
    return Param(name, si, meta["unit"], str(raw["source"]), rng_si, str(raw.get("note", "")))


def load_block(cls: type, section: Any, block: str, path: Path, registry: dict) -> Any:
    if not isinstance(section, Mapping):
        raise ConfigError(f"{path}: section '{block}' missing or not a mapping")
    known = {f.name for f in dataclasses.fields(cls)}
    extra = set(section) - known
    if extra:
        raise ConfigError(f"{path}: unknown field(s) in '{block}': {sorted(extra)}")
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        name = f"{block}.{f.name}"
        if f.name not in section:
            raise ConfigError(f"{path}: field '{name}' is missing")
        raw = section[f.name]
        if f.metadata["axis"]:
            if not isinstance(raw, Mapping) or set(raw) != set(AXES):
                raise ConfigError(f"{path}: field '{name}' needs exactly the keys az and el")
            vals = {}
            for ax in AXES:
                p = param(raw[ax], f"{name}.{ax}", f.metadata, path)
                registry[p.name] = p
                vals[ax] = p.value
            kwargs[f.name] = vals
        else:
            p = param(raw, name, f.metadata, path)
            registry[p.name] = p
            kwargs[f.name] = p.value
    return cls(**kwargs)


def number_meta(unit: str) -> dict:
    return dict(unit=unit, axis=False, vector=False, integer=False, positive=True, nonzero=True)
