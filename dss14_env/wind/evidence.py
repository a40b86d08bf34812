"""The public evidence on the wind loads of a DSN-class dish (``configs/wind_evidence.yaml``).

[R] Table 4 fixes the servo error at the drive encoders, which a soft drive in weak wind and a
stiff drive in strong wind both meet.  The wind-moment coefficients tell them apart: the file
holds every public figure that bears on them (source, value, conditions, how directly it was
read) and, under ``accepted``, the range each coefficient of the model's normalisation
``C = M / (q A D)`` (:mod:`dss14_env.wind.loads`) may take on that evidence.  ``dss14
reproduce`` checks the calibrated coefficients against these ranges (docs/wind.md section 6).

>>> ev = load_wind_evidence()
>>> lo, hi = ev.accepted["el_front"].range
>>> bool(0 < lo < ev.accepted["el_front"].nominal < hi)
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from dss14_env.core.schema import ConfigError, read_config

#: the coefficients of the model (``<axis>_<direction>``) and their keys in the file
COEFFICIENT_KEYS: Mapping[str, str] = MappingProxyType(
    {"el_front": "c_el_front", "az_side": "c_az_side", "az_front": "c_az_front", "el_side": "c_el_side"})


@dataclass(frozen=True)
class AcceptedCoefficient:
    """What the evidence admits for one moment coefficient (dimensionless).

    :param range: ``(lo, hi)`` accepted on the evidence
    :param nominal: the evidence's central estimate
    :param basis: which evidence rows it rests on
    """

    range: tuple[float, float]
    nominal: float
    basis: str


@dataclass(frozen=True)
class WindEvidence:
    """The evidence file: its rows as written and the accepted coefficients that have any."""

    rows: Mapping[str, Mapping[str, Any]]
    accepted: Mapping[str, AcceptedCoefficient]
    source: str


def _number(x: Any, field: str, source: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or x <= 0:
        raise ConfigError(f"{source}: field '{field}': must be a positive finite number, got {x!r}")
    return float(x)


def load_wind_evidence(path: str | Path | None = None) -> WindEvidence:
    """Load ``configs/wind_evidence.yaml`` (or ``path``, or a shipped name).

    :raises ConfigError: naming the field and the file (an accepted range that is not two
        positive numbers in order around its nominal value)
    """
    data, source = read_config("wind_evidence" if path is None else path)
    rows, acc = data.get("evidence"), data.get("accepted")
    if not isinstance(rows, Mapping) or not isinstance(acc, Mapping):
        raise ConfigError(f"{source}: must have the mappings 'evidence' and 'accepted'")
    out = {}
    for name, key in COEFFICIENT_KEYS.items():
        entry = acc.get(key)
        if not isinstance(entry, Mapping):
            raise ConfigError(f"{source}: field 'accepted.{key}': must be a mapping, got {entry!r}")
        if entry.get("range") is None:
            continue  # no public figure
        rng = entry["range"]
        if not isinstance(rng, (list, tuple)) or len(rng) != 2:
            raise ConfigError(f"{source}: field 'accepted.{key}.range': must be [lo, hi], got {rng!r}")
        lo, hi = (_number(v, f"accepted.{key}.range", source) for v in rng)
        nom = _number(entry.get("nominal"), f"accepted.{key}.nominal", source)
        if not lo <= nom <= hi:
            raise ConfigError(f"{source}: field 'accepted.{key}': nominal {nom:g} outside its range "
                              f"[{lo:g}, {hi:g}]")
        out[name] = AcceptedCoefficient((lo, hi), nom, str(entry.get("basis", "")))
    return WindEvidence(MappingProxyType(dict(rows)), MappingProxyType(out), source)


__all__ = ["AcceptedCoefficient", "COEFFICIENT_KEYS", "WindEvidence", "load_wind_evidence"]
