"""Typed, validated model configuration loaded from ``configs/*.yaml``.

Each parameter in the YAML file is a mapping ``{value, unit, source[, range][, note]}`` in the
report's units.  :func:`load_model_config` converts every value to SI
(:mod:`dss14_env.units`), checks it (finite, sign, range, unit family) and returns frozen
dataclasses, one per model block.  A wrong or missing value raises :class:`ConfigError`
naming the field and the file.

>>> cfg = load_model_config()
>>> round(cfg.hydraulics.d_motor * 1e6, 3)   # cm^3/rad -> m^3/rad
25.2
>>> cfg.params["hydraulics.zeta_o"].range
(0.6, 0.8)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

import yaml

from .units import UNITS, si_unit, to_si

AXES = ("az", "el")


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


def _spec(unit: str, *, axis: bool = False, vector: bool = False, integer: bool = False,
          positive: bool = True, nonzero: bool = True) -> Any:
    return field(metadata=dict(unit=unit, axis=axis, vector=vector, integer=integer,
                               positive=positive, nonzero=nonzero))


@dataclass(frozen=True)
class BoardConfig:
    """Electronics board, [R] Eqs. (1)-(10)."""

    k_r: float = _spec("V/(rad/s)")
    k_t: float = _spec("V/(rad/s)")
    g_r1: float = _spec("1")
    g_r2: float = _spec("1", positive=False)
    g_s: float = _spec("A/V")
    tau_zero: float = _spec("s")
    tau_pole: float = _spec("s")
    g_to: dict = _spec("1", axis=True)
    n_o: dict = _spec("1", axis=True)


@dataclass(frozen=True)
class HydraulicsConfig:
    """Hydraulic system, [R] Eqs. (11)-(34), Tables 1-3."""

    zeta_o: float = _spec("1")
    omega_o: float = _spec("rad/s")
    k_a_report: float = _spec("m^3/s/A")
    k_s: float = _spec("m^3/s/Pa")
    k_p: float = _spec("m^3/s/Pa")
    d_motor: float = _spec("m^3/rad")
    k_v: float = _spec("1")
    mu: float = _spec("Pa*s")
    k_a2: float = _spec("m^3")
    beta: float = _spec("Pa")
    v_o: dict = _spec("m^3", axis=True)


@dataclass(frozen=True)
class GearboxConfig:
    """Gear train, [R] Eqs. (35)-(37) and Fig. 1 (constants the report omits)."""

    j_m: float = _spec("kg*m^2")
    n_t: float = _spec("1")
    n_p: float = _spec("1")


@dataclass(frozen=True)
class StructureConfig:
    """Lumped-parameter description of the antenna structure (docs/model.md section 5)."""

    elevation_angle: float = _spec("rad")
    modal_damping: float = _spec("1")
    r_rail_az: float = _spec("m")
    alpha_az: float = _spec("rad")
    m_node_az: float = _spec("kg")
    k_mesh_az: float = _spec("N/m")
    k_radial_az: float = _spec("N/m")
    j_ring: float = _spec("kg*m^2")
    j_alidade: tuple = _spec("kg*m^2", vector=True)
    j_tip_az: float = _spec("kg*m^2")
    k_az_chain: tuple = _spec("N*m/rad", vector=True)
    r_rail_el: float = _spec("m")
    alpha_el: float = _spec("rad")
    m_node_el: float = _spec("kg")
    k_mesh_el: float = _spec("N/m")
    k_radial_el: float = _spec("N/m")
    j_wheel_el: float = _spec("kg*m^2")
    j_tip_el: float = _spec("kg*m^2")
    j_counterweight: float = _spec("kg*m^2")
    k_wheel_el: float = _spec("N*m/rad")
    k_counterweight: float = _spec("N*m/rad")
    el_drive_lever: float = _spec("m", positive=False, nonzero=False)
    n_ribs: int = _spec("1", integer=True)
    n_rib_nodes: int = _spec("1", integer=True)
    rib_r_inner: float = _spec("m")
    rib_r_outer: float = _spec("m")
    rib_node_mass: float = _spec("kg")
    k_rib: float = _spec("N/m")
    k_hoop: float = _spec("N/m")
    quad_leg_height: float = _spec("m")
    subreflector_height: float = _spec("m")
    m_quad_node: float = _spec("kg")
    m_subreflector: float = _spec("kg")
    k_quad: float = _spec("N/m")
    subreflector_pointing_factor: float = _spec("1", positive=False, nonzero=False)


@dataclass(frozen=True)
class ReductionConfig:
    """Modal reduction, [R] Eq. (55)."""

    n_flexible_modes: int = _spec("1", integer=True)


@dataclass(frozen=True)
class GainSet:
    """PI gains of [R] Eq. (58), acting on the servo error in axis radians."""

    kp: float
    ki: float


@dataclass(frozen=True)
class CalibrationTargets:
    """Published figures the calibration solves for (dss14_env/calibration.py)."""

    rate_loop_dc: float = _spec("1")
    rate_loop_flat_freq: float = _spec("Hz")
    rate_loop_flat_ratio: float = _spec("1")
    gearbox_peak: dict = _spec("Hz", axis=True)
    structure_az_peaks: tuple = _spec("Hz", vector=True)
    cross_coupling_peak: float = _spec("1")


@dataclass(frozen=True)
class ModelConfig:
    """The whole model configuration (SI values) plus the flat parameter registry."""

    board: BoardConfig
    hydraulics: HydraulicsConfig
    gearbox: GearboxConfig
    structure: StructureConfig
    reduction: ReductionConfig
    gain_sets: dict
    calibration: CalibrationTargets
    params: dict  # "block.name" or "block.name.axis" -> Param
    path: str

    def replace(self, **overrides: float) -> "ModelConfig":
        """Return a copy with some scalar parameters replaced (SI values).

        :param overrides: ``{"hydraulics__zeta_o": 0.6, ...}`` (block and field joined by a
            double underscore); per-axis fields take ``{"az": .., "el": ..}``.
        """
        blocks: dict[str, Any] = {}
        for key, val in overrides.items():
            block, _, name = key.partition("__")
            obj = blocks.get(block, getattr(self, block, None))
            if obj is None or not dataclasses.is_dataclass(obj) or name not in {
                    f.name for f in dataclasses.fields(obj)}:
                raise ConfigError(f"unknown parameter {key!r} (use block__field)")
            blocks[block] = dataclasses.replace(obj, **{name: val})
        return dataclasses.replace(self, **blocks)


def default_config_path(name: str = "model.yaml") -> Path:
    """Path of a configuration file shipped in the ``configs`` package."""
    return Path(str(resources.files("configs").joinpath(name)))


def _read_yaml(path: Path) -> Mapping[str, Any]:
    if not path.is_file():
        raise ConfigError(f"configuration file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from exc
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: top level must be a mapping")
    return data


def _param(raw: Any, name: str, meta: Mapping[str, Any], path: Path) -> Param:
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


def _block(cls: type, section: Any, block: str, path: Path, registry: dict) -> Any:
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
                p = _param(raw[ax], f"{name}.{ax}", f.metadata, path)
                registry[p.name] = p
                vals[ax] = p.value
            kwargs[f.name] = vals
        else:
            p = _param(raw, name, f.metadata, path)
            registry[p.name] = p
            kwargs[f.name] = p.value
    return cls(**kwargs)


def load_model_config(path: str | Path | None = None) -> ModelConfig:
    """Load and validate the model configuration.

    :param path: YAML file; default: the shipped ``configs/model.yaml``
    :return: the configuration in SI units
    :raises ConfigError: naming the field and file of the first problem found
    """
    path = Path(path) if path is not None else default_config_path()
    data = _read_yaml(path)
    registry: dict[str, Param] = {}
    board = _block(BoardConfig, data.get("board"), "board", path, registry)
    hyd = _block(HydraulicsConfig, data.get("hydraulics"), "hydraulics", path, registry)
    gear = _block(GearboxConfig, data.get("gearbox"), "gearbox", path, registry)
    struct = _block(StructureConfig, data.get("structure"), "structure", path, registry)
    red = _block(ReductionConfig, data.get("reduction"), "reduction", path, registry)
    cal = _block(CalibrationTargets, data.get("calibration"), "calibration", path, registry)
    pl = data.get("position_loop")
    if not isinstance(pl, Mapping) or not isinstance(pl.get("gain_sets"), Mapping) or not pl["gain_sets"]:
        raise ConfigError(f"{path}: field 'position_loop.gain_sets' is missing or empty")
    gains = {}
    for gname, g in pl["gain_sets"].items():
        if not isinstance(g, Mapping) or set(g) != {"kp", "ki"}:
            raise ConfigError(f"{path}: field 'position_loop.gain_sets.{gname}' needs kp and ki")
        kp = _param(g["kp"], f"position_loop.gain_sets.{gname}.kp", _meta("1/s"), path)
        ki = _param(g["ki"], f"position_loop.gain_sets.{gname}.ki", _meta("1/s^2"), path)
        gains[str(gname)] = GainSet(kp.value, ki.value)
    if struct.rib_r_inner >= struct.rib_r_outer:
        raise ConfigError(f"{path}: field 'structure.rib_r_inner' must be below rib_r_outer")
    if len(struct.j_alidade) + 1 != len(struct.k_az_chain):
        raise ConfigError(f"{path}: field 'structure.k_az_chain' needs len(j_alidade)+1 entries")
    if not 0 < struct.modal_damping < 1:
        raise ConfigError(f"{path}: field 'structure.modal_damping' must be in (0, 1)")
    if len(cal.structure_az_peaks) != 2:
        raise ConfigError(f"{path}: field 'calibration.structure_az_peaks' needs 2 entries")
    return ModelConfig(board, hyd, gear, struct, red, gains, cal, registry, str(path))


def _meta(unit: str) -> dict:
    return dict(unit=unit, axis=False, vector=False, integer=False, positive=True, nonzero=True)
