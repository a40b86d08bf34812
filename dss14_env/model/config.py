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
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dss14_env.core.schema import ConfigError, Param, load_section, read_config, spec


@dataclass(frozen=True)
class BoardConfig:
    """Electronics board, [R] Eqs. (1)-(10)."""

    k_r: float = spec("V/(rad/s)", lo=0.0, lo_open=True)
    k_t: float = spec("V/(rad/s)", lo=0.0, lo_open=True)
    g_r1: float = spec("1", lo=0.0, lo_open=True)
    g_r2: float = spec("1")
    g_s: float = spec("A/V", lo=0.0, lo_open=True)
    tau_zero: float = spec("s", lo=0.0, lo_open=True)
    tau_pole: float = spec("s", lo=0.0, lo_open=True)
    g_to: dict = spec("1", lo=0.0, lo_open=True, axis=True)
    n_o: dict = spec("1", lo=0.0, lo_open=True, axis=True)


@dataclass(frozen=True)
class HydraulicsConfig:
    """Hydraulic system, [R] Eqs. (11)-(34), Tables 1-3."""

    zeta_o: float = spec("1", lo=0.0, lo_open=True)
    omega_o: float = spec("rad/s", lo=0.0, lo_open=True)
    k_a_report: float = spec("m^3/s/A", lo=0.0, lo_open=True)
    k_s: float = spec("m^3/s/Pa", lo=0.0, lo_open=True)
    k_p: float = spec("m^3/s/Pa", lo=0.0, lo_open=True)
    d_motor: float = spec("m^3/rad", lo=0.0, lo_open=True)
    k_v: float = spec("1", lo=0.0, lo_open=True)
    mu: float = spec("Pa*s", lo=0.0, lo_open=True)
    k_a2: float = spec("m^3", lo=0.0, lo_open=True)
    beta: float = spec("Pa", lo=0.0, lo_open=True, hi=1.0e12)  # oil: ~1.3e9 Pa; steel 1.6e11
    v_o: dict = spec("m^3", lo=0.0, lo_open=True, axis=True)


@dataclass(frozen=True)
class GearboxConfig:
    """Gear train, [R] Eqs. (35)-(37) and Fig. 1 (constants the report omits)."""

    j_m: float = spec("kg*m^2", lo=0.0, lo_open=True)
    n_t: float = spec("1", lo=0.0, lo_open=True)
    n_p: float = spec("1", lo=0.0, lo_open=True)


@dataclass(frozen=True)
class StructureConfig:
    """Lumped-parameter description of the antenna structure (docs/model.md section 5)."""

    elevation_angle: float = spec("rad", lo=0.0, lo_open=True)
    modal_damping: float = spec("1", lo=0.0, lo_open=True, hi=1.0, hi_open=True)
    r_rail_az: float = spec("m", lo=0.0, lo_open=True)
    alpha_az: float = spec("rad", lo=0.0, lo_open=True)
    m_node_az: float = spec("kg", lo=0.0, lo_open=True)
    k_mesh_az: float = spec("N/m", lo=0.0, lo_open=True)
    k_radial_az: float = spec("N/m", lo=0.0, lo_open=True)
    j_ring: float = spec("kg*m^2", lo=0.0, lo_open=True)
    j_alidade: tuple = spec("kg*m^2", kind="list", lo=0.0, lo_open=True)
    j_tip_az: float = spec("kg*m^2", lo=0.0, lo_open=True)
    k_az_chain: tuple = spec("N*m/rad", kind="list", lo=0.0, lo_open=True)
    r_rail_el: float = spec("m", lo=0.0, lo_open=True)
    alpha_el: float = spec("rad", lo=0.0, lo_open=True)
    m_node_el: float = spec("kg", lo=0.0, lo_open=True)
    k_mesh_el: float = spec("N/m", lo=0.0, lo_open=True)
    k_radial_el: float = spec("N/m", lo=0.0, lo_open=True)
    j_wheel_el: float = spec("kg*m^2", lo=0.0, lo_open=True)
    j_tip_el: float = spec("kg*m^2", lo=0.0, lo_open=True)
    j_counterweight: float = spec("kg*m^2", lo=0.0, lo_open=True)
    k_wheel_el: float = spec("N*m/rad", lo=0.0, lo_open=True)
    k_counterweight: float = spec("N*m/rad", lo=0.0, lo_open=True)
    el_drive_lever: float = spec("m")
    # at most 24 x 12 nodes (2.25 x the shipped 16 x 8): the model's eigenproblems and balanced
    # reduction grow with the cube of their number (32 x 16 took 126 s to build, 16 x 8 7.8 s,
    # on a loaded 2-core machine)
    n_ribs: int = spec("1", kind="integer", lo=1, hi=24)
    n_rib_nodes: int = spec("1", kind="integer", lo=1, hi=12)
    rib_r_inner: float = spec("m", lo=0.0, lo_open=True)
    rib_r_outer: float = spec("m", lo=0.0, lo_open=True)
    rib_node_mass: float = spec("kg", lo=0.0, lo_open=True)
    k_rib: float = spec("N/m", lo=0.0, lo_open=True)
    k_hoop: float = spec("N/m", lo=0.0, lo_open=True)
    quad_leg_height: float = spec("m", lo=0.0, lo_open=True)
    subreflector_height: float = spec("m", lo=0.0, lo_open=True)
    m_quad_node: float = spec("kg", lo=0.0, lo_open=True)
    m_subreflector: float = spec("kg", lo=0.0, lo_open=True)
    k_quad: float = spec("N/m", lo=0.0, lo_open=True)
    subreflector_pointing_factor: float = spec("1")


@dataclass(frozen=True)
class ReductionConfig:
    """Modal reduction, [R] Eq. (55)."""

    n_flexible_modes: int = spec("1", kind="integer", lo=1)


@dataclass(frozen=True)
class GainSet:
    """PI gains of [R] Eq. (58), acting on the servo error in axis radians."""

    kp: float
    ki: float


@dataclass(frozen=True)
class CalibrationTargets:
    """Published figures the calibration solves for (dss14_env/model/calibration.py)."""

    rate_loop_dc: float = spec("1", lo=0.0, lo_open=True)
    rate_loop_flat_freq: float = spec("Hz", lo=0.0, lo_open=True)
    rate_loop_flat_ratio: float = spec("1", lo=0.0, lo_open=True)
    gearbox_peak: dict = spec("Hz", lo=0.0, lo_open=True, axis=True)
    structure_az_peaks: tuple = spec("Hz", kind="list", lo=0.0, lo_open=True)
    cross_coupling_peak: float = spec("1", lo=0.0, lo_open=True)
    #: the gain set (a name of ``position_loop.gain_sets``) the cross-coupling peak is read with
    cross_coupling_gain_set: str = spec(None, kind="str")


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
    #: the file's ``recalibrate_wind`` key: the environment refits the wind-load coefficients
    #: to [R] Table 4 on this model instead of keeping the shipped ones (default False)
    recalibrate_wind: bool = False

    def replace(self, **overrides: float) -> ModelConfig:
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


#: ranged parameters whose value must be the top of their range: the report's valve gain
#: (Hill's estimate, [R] Table 1) stands for the valve gain the calibration solves from Fig. 17
#: (``calibration.rate_loop_*``), so a value of its own could not move the model; its range sets
#: only the spread over which parameter randomisation scales the calibrated gain (low end / top)
RANGE_TOP_ONLY = ("hydraulics.k_a_report",)

#: sections of ``configs/model.yaml`` and their dataclasses
SECTIONS = {"board": BoardConfig, "hydraulics": HydraulicsConfig, "gearbox": GearboxConfig,
            "structure": StructureConfig, "reduction": ReductionConfig,
            "calibration": CalibrationTargets}


@dataclass(frozen=True)
class GainSetSpec:
    """One gain set of ``position_loop.gain_sets`` as written in the file."""

    kp: float = spec("1/s", lo=0.0, lo_open=True)
    ki: float = spec("1/s^2", lo=0.0, lo_open=True)


def _merged(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``over``'s entries laid on top, mappings merged key by key (a leaf written
    as ``{value: ...}`` keeps the base leaf's unit, range and source unless it gives its own).
    """
    out = dict(base)
    for key, val in over.items():
        out[key] = (_merged(out[key], val) if isinstance(val, Mapping) and isinstance(out.get(key), Mapping)
                    else val)
    return out


def _with_base(data: Mapping[str, Any], source: str) -> dict[str, Any]:
    """A model file's content with its ``base`` (a model file or shipped name, e.g.
    ``base: model``) read first and the file's own entries laid on top (:func:`_merged`); one
    level: a base file names no base itself.

    :raises ConfigError: a ``base`` that is not a name, or one with a base of its own
    """
    if "base" not in data:
        return dict(data)
    name = data["base"]
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{source}: field 'base': must name a model file or a shipped model "
                          f"(e.g. 'model'), got {name!r}")
    base, base_source = read_config(name)
    if "base" in base:
        raise ConfigError(f"{source}: field 'base': {base_source} names a base itself; a model "
                          f"file builds on one complete model file")
    return _merged(base, {k: v for k, v in data.items() if k != "base"})


def load_model_config(path: str | Path | None = None) -> ModelConfig:
    """Load and validate the model configuration.

    :param path: YAML file or shipped configuration name; default: the shipped
        ``configs/model.yaml``.  A file may build on another with ``base: <file or shipped
        name>`` and give only what differs (the shipped drive variants ``model_soft`` and
        ``model_stiff`` do)
    :return: the configuration in SI units
    :raises ConfigError: naming the field and file of the first problem found
    """
    data, source = read_config("model" if path is None else path, kind="model")
    data = _with_base(data, source)
    registry: dict[str, Param] = {}
    extra = set(data) - set(SECTIONS) - {"position_loop", "recalibrate_wind"}
    if extra:
        raise ConfigError(f"{source}: unknown section(s) {sorted(extra)}; known: "
                          f"{sorted(SECTIONS) + ['position_loop', 'recalibrate_wind', 'base']}")
    recalibrate = data.get("recalibrate_wind", False)
    if not isinstance(recalibrate, bool):
        raise ConfigError(f"{source}: field 'recalibrate_wind': must be true or false, got {recalibrate!r}")
    kw = dict(documented=True, registry=registry, defaults=False)
    blocks = {name: load_section(cls, data.get(name), source, name, **kw)
              for name, cls in SECTIONS.items()}
    pl = data.get("position_loop")
    if not isinstance(pl, Mapping) or not isinstance(pl.get("gain_sets"), Mapping) or not pl["gain_sets"]:
        raise ConfigError(f"{source}: field 'position_loop.gain_sets': must be a non-empty mapping "
                          f"of gain sets, got {pl!r}")
    gains = {}
    for gname, g in pl["gain_sets"].items():
        gs = load_section(GainSetSpec, g, source, f"position_loop.gain_sets.{gname}", **kw)
        gains[str(gname)] = GainSet(gs.kp, gs.ki)
    struct, cal = blocks["structure"], blocks["calibration"]
    for name in RANGE_TOP_ONLY:
        p, (block, key) = registry[name], name.split(".")
        if p.range is not None and not math.isclose(p.value, p.range[1], rel_tol=1e-12):
            leaf = data[block][key]
            raise ConfigError(f"{source}: field '{name}': must be the top of its range, "
                              f"{leaf['range'][1]!r} {leaf['unit']} (the calibration solves the model's "
                              f"valve gain from calibration.rate_loop_*; the range sets only its "
                              f"randomised spread), got {leaf['value']!r}")
    if struct.rib_r_inner >= struct.rib_r_outer:
        raise ConfigError(f"{source}: field 'structure.rib_r_inner': must be below rib_r_outer "
                          f"({struct.rib_r_outer} m), got {struct.rib_r_inner}")
    if len(struct.j_alidade) + 1 != len(struct.k_az_chain):
        raise ConfigError(f"{source}: field 'structure.k_az_chain': must have len(j_alidade) + 1 = "
                          f"{len(struct.j_alidade) + 1} entries, got {len(struct.k_az_chain)}")
    if len(cal.structure_az_peaks) != 2:
        raise ConfigError(f"{source}: field 'calibration.structure_az_peaks': must have 2 entries, "
                          f"got {len(cal.structure_az_peaks)}")
    if cal.cross_coupling_gain_set not in gains:
        raise ConfigError(f"{source}: field 'calibration.cross_coupling_gain_set': must name a gain set of "
                          f"position_loop.gain_sets {sorted(gains)}, got {cal.cross_coupling_gain_set!r}")
    return ModelConfig(blocks["board"], blocks["hydraulics"], blocks["gearbox"], struct,
                       blocks["reduction"], gains, cal, registry, source, recalibrate)
