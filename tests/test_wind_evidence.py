"""``configs/wind_evidence.yaml`` (docs/wind.md section 6): every row complete, and the accepted
ranges the product of the solid-dish rows and the porosity factor they name."""

from __future__ import annotations

import math

import pytest

from dss14_env.core.schema import read_config

ROW_KEYS = {"quantity", "value", "range", "unit", "conditions", "source", "url", "read", "confidence"}


@pytest.fixture(scope="module")
def evidence() -> dict:
    data, _ = read_config("wind_evidence")
    return data


def test_rows_are_complete_and_their_values_inside_their_ranges(evidence: dict) -> None:
    for name, row in evidence["evidence"].items():
        assert set(row) == ROW_KEYS, name
        assert row["read"] in ("full_text", "abstract", "derived"), name
        assert row["confidence"] in ("high", "medium", "low"), name
        if row["range"] is not None:
            lo, hi = row["range"]
            assert math.isfinite(lo) and math.isfinite(hi) and lo <= hi, name
            if row["value"] is not None:
                assert lo <= row["value"] <= hi, name


@pytest.mark.parametrize("coef", ["c_el_front", "c_az_side"])
def test_accepted_range_is_the_solid_row_times_the_porosity_factor(evidence: dict, coef: str) -> None:
    acc = evidence["accepted"][coef]
    solid = evidence["evidence"][acc["solid_row"]]["range"]
    p_lo, p_hi = evidence["porosity_factor_applied"]
    lo, hi = acc["range"]
    # the file keeps two or three significant figures
    assert lo == pytest.approx(solid[0] * p_lo, rel=0.03)
    assert hi == pytest.approx(solid[1] * p_hi, rel=0.03)
    assert acc["report_consistent"] == pytest.approx(solid, rel=0.03)
    assert 0 < lo <= acc["nominal"] <= hi


def test_coefficients_without_public_figures_have_no_range(evidence: dict) -> None:
    assert set(evidence["accepted"]) == {"c_el_front", "c_az_side", "c_az_front", "c_el_side"}
    for coef in ("c_az_front", "c_el_side"):
        assert evidence["accepted"][coef]["range"] is None
