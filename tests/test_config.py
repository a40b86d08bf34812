"""Configuration loader: SI conversions and validation errors.

Expected SI values are hand conversions of the numbers printed in the report (and kept in
``configs/model.yaml`` in the report's units); they are not taken from ``dss14_env.core.units``.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from dss14_env.core.schema import ConfigError, default_config_path
from dss14_env.model.config import ModelConfig, load_model_config

IN3 = 16.387064e-6  # m^3 per cubic inch (exact: 2.54^3 cm^3)


@pytest.fixture(scope="module")
def cfg() -> ModelConfig:
    return load_model_config()


@pytest.fixture(scope="module")
def raw() -> dict:
    data = yaml.safe_load(default_config_path().read_text())
    assert isinstance(data, dict)
    return data


def test_default_config_loads(cfg: ModelConfig) -> None:
    assert Path(cfg.path) == default_config_path()
    assert default_config_path().is_file()
    for block in ("board", "hydraulics", "gearbox", "structure", "reduction", "calibration"):
        assert getattr(cfg, block) is not None
    assert set(cfg.gain_sets) == {"kp1", "kp0.7"}
    assert cfg.gain_sets["kp1"].kp == 1.0 and cfg.gain_sets["kp1"].ki == 0.3
    assert cfg.gain_sets["kp0.7"].kp == 0.7 and cfg.gain_sets["kp0.7"].ki == 0.2
    assert cfg.reduction.n_flexible_modes == 22
    assert isinstance(cfg.structure.n_ribs, int)


# (getter, expected SI value written out by hand from the printed number and unit: [R]'s, or for mu
# and k_a2 the shipped drive's, docs/model.md section 7)
SI_CASES: dict[str, tuple[Callable[[ModelConfig], float], float]] = {
    "d_motor 25.2 cm^3/rad": (lambda c: c.hydraulics.d_motor, 25.2e-6),
    "beta 1.29e6 kPa": (lambda c: c.hydraulics.beta, 1.29e9),
    "k_a_report 38300 in^3/s/A": (lambda c: c.hydraulics.k_a_report, 38300 * IN3),
    "k_p 0.0055 cm^3/s/kPa": (lambda c: c.hydraulics.k_p, 5.5e-12),
    "k_s 0.002 cm^3/s/kPa": (lambda c: c.hydraulics.k_s, 2.0e-12),
    "mu 1.5e-3 kPa*s": (lambda c: c.hydraulics.mu, 1.5),
    "k_a2 4.1e-4 cm^3": (lambda c: c.hydraulics.k_a2, 4.1e-10),
    "v_o az 27200 cm^3": (lambda c: c.hydraulics.v_o["az"], 0.0272),
    "v_o el 24500 cm^3": (lambda c: c.hydraulics.v_o["el"], 0.0245),
    "omega_o 345.56 rad/s": (lambda c: c.hydraulics.omega_o, 345.56),
    "elevation 45 deg": (lambda c: c.structure.elevation_angle, math.pi / 4),
    "alpha_az 30 deg": (lambda c: c.structure.alpha_az, math.pi / 6),
    "k_r 1212.6 V/(rad/s)": (lambda c: c.board.k_r, 1212.6),
    "g_s 4.42e-5 A/V": (lambda c: c.board.g_s, 4.42e-5),
    "g_to az 0.151": (lambda c: c.board.g_to["az"], 0.151),
    "g_to el 0.127": (lambda c: c.board.g_to["el"], 0.127),
}


@pytest.mark.parametrize("case", list(SI_CASES))
def test_si_conversion(cfg: ModelConfig, case: str) -> None:
    getter, expected = SI_CASES[case]
    assert getter(cfg) == pytest.approx(expected, rel=1e-12)


def test_k_a_report_is_the_inch_column(cfg: ModelConfig) -> None:
    # 38,300 in^3/s/A = 627,627 cm^3/s/A = 0.6276 m^3/s/A (not the 2.54-slip 97,300 cm^3/s/A)
    assert cfg.hydraulics.k_a_report == pytest.approx(0.62762455, rel=1e-7)


def test_param_registry_ranges_in_si(cfg: ModelConfig) -> None:
    assert cfg.params["hydraulics.zeta_o"].range == (0.6, 0.8)
    lo, hi = cfg.params["hydraulics.k_a_report"].range
    assert lo == pytest.approx(23300 * IN3, rel=1e-12)
    assert hi == pytest.approx(38300 * IN3, rel=1e-12)
    lo, hi = cfg.params["hydraulics.mu"].range
    assert (lo, hi) == (pytest.approx(0.28, rel=1e-12), pytest.approx(2.8, rel=1e-12))
    assert cfg.params["hydraulics.d_motor"].unit == "m^3/rad"
    assert cfg.params["hydraulics.v_o.el"].value == pytest.approx(0.0245, rel=1e-12)


# ------------------------------------------------------------------ error cases
def _write(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _expect_error(path: Path, *fragments: str) -> str:
    with pytest.raises(ConfigError) as info:
        load_model_config(path)
    msg = str(info.value)
    assert str(path) in msg, msg
    for frag in fragments:
        assert frag in msg, msg
    return msg


def test_unmodified_copy_loads(tmp_path: Path, raw: dict) -> None:
    """The round trip through yaml.safe_dump is itself harmless (guards the error tests)."""
    cfg2 = load_model_config(_write(tmp_path, copy.deepcopy(raw)))
    assert cfg2.hydraulics.beta == pytest.approx(1.29e9, rel=1e-12)
    assert cfg2.hydraulics.d_motor == pytest.approx(2.52e-5, rel=1e-12)


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "does_not_exist.yaml"
    with pytest.raises(ConfigError) as info:
        load_model_config(path)
    assert str(path) in str(info.value)


def test_missing_field(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    del data["hydraulics"]["k_v"]
    _expect_error(_write(tmp_path, data), "hydraulics.k_v")


def test_missing_section(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    del data["gearbox"]
    _expect_error(_write(tmp_path, data), "gearbox")


# (block, field, replacement entry, message fragment besides the field name)
BAD_VALUES: list[tuple[str, str, dict[str, Any], str]] = [
    ("hydraulics", "k_v", {"value": "abc", "unit": "1", "source": "t"}, "must be a number"),
    ("hydraulics", "d_motor", {"value": -25.2, "unit": "cm^3/rad", "source": "t"}, "> 0"),
    ("hydraulics", "d_motor", {"value": 25.2, "unit": "kg", "source": "t"}, "kg"),
    ("hydraulics", "beta", {"value": 1.29e6, "unit": "furlong", "source": "t"}, "furlong"),
    ("hydraulics", "zeta_o", {"value": 0.9, "unit": "1", "range": [0.6, 0.8], "source": "t"},
     "range"),
    ("gearbox", "j_m", {"value": 0.0, "unit": "kg*m^2", "source": "t"}, "> 0"),
    ("hydraulics", "mu", {"value": float("nan"), "unit": "kPa*s", "source": "t"}, "nan"),
    ("structure", "n_ribs", {"value": 2.5, "unit": "1", "source": "t"}, "integer"),
    ("hydraulics", "k_v", {"value": True, "unit": "1", "source": "t"}, "must be a number"),
    ("hydraulics", "k_v", {"value": 0.0438, "unit": "1"}, "source"),
    ("structure", "modal_damping", {"value": 1.5, "unit": "1", "source": "t"}, "< 1"),
]


@pytest.mark.parametrize("block,name,entry,fragment", BAD_VALUES,
                         ids=[f"{b}.{n}-{f}" for b, n, _, f in BAD_VALUES])
def test_bad_value(tmp_path: Path, raw: dict, block: str, name: str, entry: dict,
                   fragment: str) -> None:
    data = copy.deepcopy(raw)
    data[block][name] = entry
    _expect_error(_write(tmp_path, data), f"{block}.{name}", fragment)


def test_wrong_unit_family_names_expected_family(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    data["hydraulics"]["d_motor"]["unit"] = "kg"
    msg = _expect_error(_write(tmp_path, data), "hydraulics.d_motor")
    assert "m^3/rad" in msg


def test_unknown_extra_field(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    data["hydraulics"]["k_bogus"] = {"value": 1.0, "unit": "1", "source": "t"}
    _expect_error(_write(tmp_path, data), "hydraulics", "k_bogus")


def test_per_axis_field_lacking_el(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    del data["hydraulics"]["v_o"]["el"]
    _expect_error(_write(tmp_path, data), "hydraulics.v_o", "el")


def test_per_axis_field_el_value_bad(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    data["hydraulics"]["v_o"]["el"]["value"] = -1.0
    _expect_error(_write(tmp_path, data), "hydraulics.v_o.el")


def test_range_on_vector_field(tmp_path: Path, raw: dict) -> None:
    """A ``range`` is allowed on every parameter; on a vector parameter a value outside it must
    still give a ConfigError naming the field (not a TypeError)."""
    data = copy.deepcopy(raw)
    data["structure"]["j_alidade"]["range"] = [1.0e7, 1.2e8]  # 1.5e8 entries lie above
    _expect_error(_write(tmp_path, data), "structure.j_alidade", "range")


def test_value_at_range_edge_accepted(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    data["hydraulics"]["zeta_o"]["value"] = 0.6
    assert load_model_config(_write(tmp_path, data)).hydraulics.zeta_o == 0.6


@pytest.mark.parametrize("value", [23300, 30000, 38299])
def test_k_a_report_below_the_top_of_its_range_is_refused(tmp_path: Path, raw: dict, value: float) -> None:
    """The model's valve gain is calibrated (Fig. 17): a k_a_report of its own could not move it,
    so the file may not pretend to set it."""
    data = copy.deepcopy(raw)
    data["hydraulics"]["k_a_report"]["value"] = value
    msg = _expect_error(_write(tmp_path, data), "hydraulics.k_a_report", "top of its range", "38300",
                        f"got {value}")
    assert "\n" not in msg


def test_k_a_report_range_sets_the_randomised_spread(tmp_path: Path, raw: dict) -> None:
    """A range of one's own is honoured, its top the value: randomisation scales the calibrated
    valve gain by draw / top."""
    data = copy.deepcopy(raw)
    data["hydraulics"]["k_a_report"].update(value=40000, range=[20000, 40000])
    p = load_model_config(_write(tmp_path, data)).params["hydraulics.k_a_report"]
    assert p.range[0] / p.value == pytest.approx(0.5, rel=1e-12)


def test_cross_coupling_gain_set_must_name_a_gain_set(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    data["calibration"]["cross_coupling_gain_set"]["value"] = "kp2"
    _expect_error(_write(tmp_path, data), "calibration.cross_coupling_gain_set", "kp0.7", "'kp2'")


def test_cross_coupling_gain_set_is_required(tmp_path: Path, raw: dict) -> None:
    data = copy.deepcopy(raw)
    del data["calibration"]["cross_coupling_gain_set"]
    _expect_error(_write(tmp_path, data), "calibration.cross_coupling_gain_set", "missing")
