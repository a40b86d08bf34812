"""The drive/structure split: model files built on a base, the drive variants, the wind-load
evidence and the Table 4 fit on a stiff drive."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dss14_env.core.schema import ConfigError
from dss14_env.core.units import KMH
from dss14_env.envs.plant import PLANT_FACTORIES, PlantFactory, default_plant_factory
from dss14_env.model.config import load_model_config
from dss14_env.model.variants import DRIVE_VARIANTS
from dss14_env.wind.evidence import load_wind_evidence
from dss14_env.wind.loads import three_sigma_mdeg

POINTING = ("point_el", "point_xel")


def _write(tmp_path: Path, text: str, name: str = "m.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_a_model_file_on_a_base_changes_only_what_it_gives(tmp_path: Path) -> None:
    base = load_model_config()
    cfg = load_model_config(_write(tmp_path, "base: model\nhydraulics:\n  mu: {value: 2.0e-3}\n"))
    assert cfg.hydraulics.mu == pytest.approx(2.0)  # kPa*s -> Pa*s: the base leaf's unit kept
    assert cfg.params["hydraulics.mu"].range == base.params["hydraulics.mu"].range
    assert cfg.hydraulics.k_a2 == base.hydraulics.k_a2 and cfg.structure == base.structure
    assert cfg.gain_sets == base.gain_sets


@pytest.mark.parametrize("text,match", [
    ("base: 3\n", "field 'base'"),
    ("base: ''\n", "field 'base'"),
    ("base: no_such_model_file\n", "not found"),
])
def test_a_bad_base_is_refused(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        load_model_config(_write(tmp_path, text))


def test_a_base_with_a_base_is_refused(tmp_path: Path) -> None:
    first = _write(tmp_path, "base: model\n", "first.yaml")
    with pytest.raises(ConfigError, match="names a base itself"):
        load_model_config(_write(tmp_path, f"base: {first}\n"))


def test_a_value_out_of_the_base_range_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="hydraulics.mu"):
        load_model_config(_write(tmp_path, "base: model\nhydraulics:\n  mu: {value: 1.0}\n"))


@pytest.fixture(scope="module")
def variants() -> dict[str, PlantFactory]:
    return {name: PLANT_FACTORIES.get(v.config) for name, v in DRIVE_VARIANTS.items()}


def _coefficients(f: PlantFactory) -> dict[str, float]:
    return {"el_front": float(f.loads.c_front[1]), "az_side": float(f.loads.c_side[0])}


def test_the_shipped_model_and_the_soft_variant_meet_the_evidence(variants: dict) -> None:
    acc = load_wind_evidence().accepted
    for f in (default_plant_factory(), variants["soft"]):
        for key, c in _coefficients(f).items():
            lo, hi = acc[key].range
            assert lo <= c <= hi, (f, key, c)


def test_every_variant_meets_table4(variants: dict) -> None:
    for f in variants.values():
        assert f.recalibrated and not f.loads.table4_missed


def test_the_split_moves_the_pointing_error_not_the_encoder_error(variants: dict) -> None:
    """Consequence: on the three drives the PI's encoder errors at 50 km/h are Table 4's, while
    the dish's pointing error grows with the drive's stiffness (the loads the fit needs)."""
    u = 50 * KMH
    point, coeff = [], []
    for f in (variants["soft"], default_plant_factory(), variants["stiff"]):
        pl = f.model.position_loop("kp1")
        enc_front = three_sigma_mdeg(pl, f.loads, u, "front")
        assert enc_front[1] == pytest.approx(2.6, rel=0.05)
        point.append([three_sigma_mdeg(pl, f.loads, u, "front", POINTING)[0],
                      three_sigma_mdeg(pl, f.loads, u, "side", POINTING)[1]])
        coeff.append(list(_coefficients(f).values()))
    point, coeff = np.array(point), np.array(coeff)
    assert np.all(np.diff(point, axis=0) > 0) and np.all(np.diff(coeff, axis=0) > 0)
    assert np.all(point[2] / point[0] > 2.5)


@pytest.mark.slow  # builds and calibrates one more model (10 s)
def test_a_stiff_drive_meets_table4_where_its_front_figures_compete(tmp_path: Path) -> None:
    """With mu at its range end the front wind's elevation load also moves the azimuth encoder:
    a fit weighting each figure by its accepted range meets both (a fit on the relative misfit
    left el at 2.196 mdeg, outside Table 4's 2.2-3)."""
    path = _write(tmp_path, "base: model\nrecalibrate_wind: true\nhydraulics:\n  mu: {value: 2.8e-3}\n"
                            "  k_a2: {value: 7.0e-4}\n")
    f = PlantFactory.from_model_config(path)
    assert not f.loads.table4_missed
    assert 2.2 <= f.loads.table4_fit["el_front"] <= 3.0 and f.loads.table4_fit["az_front"] <= 0.2


def test_evidence_ranges_are_checked(tmp_path: Path) -> None:
    bad = ("evidence: {}\naccepted:\n  c_el_front: {range: [0.2, 0.1], nominal: 0.15}\n"
           "  c_az_side: {range: null}\n  c_az_front: {range: null}\n  c_el_side: {range: null}\n")
    with pytest.raises(ConfigError, match="accepted.c_el_front"):
        load_wind_evidence(_write(tmp_path, bad, "ev.yaml"))


@pytest.mark.parametrize("script", ["drive_split", "rescore_policies"])
def test_generated_split_tables_are_current(script: str) -> None:
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "scripts" / f"{script}.py"
    spec = importlib.util.spec_from_file_location(script, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--check"]) == 0
