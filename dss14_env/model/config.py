"""Typed, validated model configuration loaded from ``configs/*.yaml``.

Each parameter in the YAML file is a mapping ``{value, unit, source[, range][, note]}`` in the
report's units.  :func:`load_model_config` converts every value to SI
(:mod:`dss14_env.core.units`), checks it (finite, sign, range, unit family) and returns frozen
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from dss14_env.core.schema import (
    ConfigError,
    Param,
    default_config_path,
    load_block,
    number_meta,
    param,
    read_yaml,
    spec,
)


@dataclass(frozen=True)
class BoardConfig:
    """Electronics board, [R] Eqs. (1)-(10)."""

    k_r: float = spec("V/(rad/s)")
    k_t: float = spec("V/(rad/s)")
    g_r1: float = spec("1")
    g_r2: float = spec("1", positive=False)
    g_s: float = spec("A/V")
    tau_zero: float = spec("s")
    tau_pole: float = spec("s")
    g_to: dict = spec("1", axis=True)
    n_o: dict = spec("1", axis=True)


@dataclass(frozen=True)
class HydraulicsConfig:
    """Hydraulic system, [R] Eqs. (11)-(34), Tables 1-3."""

    zeta_o: float = spec("1")
    omega_o: float = spec("rad/s")
    k_a_report: float = spec("m^3/s/A")
    k_s: float = spec("m^3/s/Pa")
    k_p: float = spec("m^3/s/Pa")
    d_motor: float = spec("m^3/rad")
    k_v: float = spec("1")
    mu: float = spec("Pa*s")
    k_a2: float = spec("m^3")
    beta: float = spec("Pa")
    v_o: dict = spec("m^3", axis=True)


@dataclass(frozen=True)
class GearboxConfig:
    """Gear train, [R] Eqs. (35)-(37) and Fig. 1 (constants the report omits)."""

    j_m: float = spec("kg*m^2")
    n_t: float = spec("1")
    n_p: float = spec("1")


@dataclass(frozen=True)
class StructureConfig:
    """Lumped-parameter description of the antenna structure (docs/model.md section 5)."""

    elevation_angle: float = spec("rad")
    modal_damping: float = spec("1")
    r_rail_az: float = spec("m")
    alpha_az: float = spec("rad")
    m_node_az: float = spec("kg")
    k_mesh_az: float = spec("N/m")
    k_radial_az: float = spec("N/m")
    j_ring: float = spec("kg*m^2")
    j_alidade: tuple = spec("kg*m^2", vector=True)
    j_tip_az: float = spec("kg*m^2")
    k_az_chain: tuple = spec("N*m/rad", vector=True)
    r_rail_el: float = spec("m")
    alpha_el: float = spec("rad")
    m_node_el: float = spec("kg")
    k_mesh_el: float = spec("N/m")
    k_radial_el: float = spec("N/m")
    j_wheel_el: float = spec("kg*m^2")
    j_tip_el: float = spec("kg*m^2")
    j_counterweight: float = spec("kg*m^2")
    k_wheel_el: float = spec("N*m/rad")
    k_counterweight: float = spec("N*m/rad")
    el_drive_lever: float = spec("m", positive=False, nonzero=False)
    n_ribs: int = spec("1", integer=True)
    n_rib_nodes: int = spec("1", integer=True)
    rib_r_inner: float = spec("m")
    rib_r_outer: float = spec("m")
    rib_node_mass: float = spec("kg")
    k_rib: float = spec("N/m")
    k_hoop: float = spec("N/m")
    quad_leg_height: float = spec("m")
    subreflector_height: float = spec("m")
    m_quad_node: float = spec("kg")
    m_subreflector: float = spec("kg")
    k_quad: float = spec("N/m")
    subreflector_pointing_factor: float = spec("1", positive=False, nonzero=False)


@dataclass(frozen=True)
class ReductionConfig:
    """Modal reduction, [R] Eq. (55)."""

    n_flexible_modes: int = spec("1", integer=True)


@dataclass(frozen=True)
class GainSet:
    """PI gains of [R] Eq. (58), acting on the servo error in axis radians."""

    kp: float
    ki: float


@dataclass(frozen=True)
class CalibrationTargets:
    """Published figures the calibration solves for (dss14_env/model/calibration.py)."""

    rate_loop_dc: float = spec("1")
    rate_loop_flat_freq: float = spec("Hz")
    rate_loop_flat_ratio: float = spec("1")
    gearbox_peak: dict = spec("Hz", axis=True)
    structure_az_peaks: tuple = spec("Hz", vector=True)
    cross_coupling_peak: float = spec("1")


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


def load_model_config(path: str | Path | None = None) -> ModelConfig:
    """Load and validate the model configuration.

    :param path: YAML file; default: the shipped ``configs/model.yaml``
    :return: the configuration in SI units
    :raises ConfigError: naming the field and file of the first problem found
    """
    path = Path(path) if path is not None else default_config_path()
    data = read_yaml(path)
    registry: dict[str, Param] = {}
    board = load_block(BoardConfig, data.get("board"), "board", path, registry)
    hyd = load_block(HydraulicsConfig, data.get("hydraulics"), "hydraulics", path, registry)
    gear = load_block(GearboxConfig, data.get("gearbox"), "gearbox", path, registry)
    struct = load_block(StructureConfig, data.get("structure"), "structure", path, registry)
    red = load_block(ReductionConfig, data.get("reduction"), "reduction", path, registry)
    cal = load_block(CalibrationTargets, data.get("calibration"), "calibration", path, registry)
    pl = data.get("position_loop")
    if not isinstance(pl, Mapping) or not isinstance(pl.get("gain_sets"), Mapping) or not pl["gain_sets"]:
        raise ConfigError(f"{path}: field 'position_loop.gain_sets' is missing or empty")
    gains = {}
    for gname, g in pl["gain_sets"].items():
        if not isinstance(g, Mapping) or set(g) != {"kp", "ki"}:
            raise ConfigError(f"{path}: field 'position_loop.gain_sets.{gname}' needs kp and ki")
        kp = param(g["kp"], f"position_loop.gain_sets.{gname}.kp", number_meta("1/s"), path)
        ki = param(g["ki"], f"position_loop.gain_sets.{gname}.ki", number_meta("1/s^2"), path)
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


