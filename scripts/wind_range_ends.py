"""A user's model at the ends of every ``range:`` of configs/model.yaml, with the shipped wind-load
coefficients (k_a_report's range excepted: its value is held at the top, the valve gain being
calibrated): the drive's compliance and the PI's exact 3σ servo errors (docs/wind.md §5).

For each range end (and the two extreme corners of the leakage term ``3 k_a2 / mu``) the model
file is the shipped one with that value; the model is built and calibrated as
``gym.make(..., model_config=...)`` builds it, the wind loads are the shipped ones
(``default_wind_loads``), and the rows give the compliance (DC axis rate per axis torque, as
the ratio to the shipped model's), the exact 3σ at 50 km/h of el in front wind and az in side
wind (kp 1), and whether a refit of the coefficients to Table 4 (``recalibrate_wind=True``)
meets its accepted ranges.

    python scripts/wind_range_ends.py            # compute, write docs/results/wind_range_ends.json, render
    python scripts/wind_range_ends.py --render   # render the committed file into docs/wind.md
    python scripts/wind_range_ends.py --check    # exit 1 if docs/wind.md is not the rendering
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from dss14_env.core.text import add_block_options, render_block

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results" / "wind_range_ends.json"
DOC = ROOT / "docs" / "wind.md"
BLOCK = "wind-range-ends"
CORNERS = {"stiffest drive (mu high, k_a2 low)": {"hydraulics.mu": "hi", "hydraulics.k_a2": "lo"},
           "most compliant drive (mu low, k_a2 high)": {"hydraulics.mu": "lo", "hydraulics.k_a2": "hi"}}


def ranges(shipped: dict) -> dict[str, tuple[float, float]]:
    """``"block.name" -> (lo, hi)`` (file units) of every ranged parameter a user may set (not
    those held at the top of their range, :data:`dss14_env.model.config.RANGE_TOP_ONLY`)."""
    from dss14_env.model.config import RANGE_TOP_ONLY

    return {f"{b}.{n}": tuple(leaf["range"]) for b, leaves in shipped.items() if isinstance(leaves, dict)
            for n, leaf in leaves.items() if isinstance(leaf, dict) and "range" in leaf
            and f"{b}.{n}" not in RANGE_TOP_ONLY}


def cases(shipped: dict) -> list[tuple[str, dict[str, float]]]:
    """(label, {name: value}) for every range end and the two corners."""
    r = ranges(shipped)
    out = [(f"{name.split('.')[1]} = {r[name][end]:g}", {name: r[name][end]})
           for name in sorted(r) for end in (0, 1)]
    for label, ends in CORNERS.items():
        out.append((label, {n: r[n][0 if e == "lo" else 1] for n, e in ends.items()}))
    return out


def compute() -> dict:
    """Build every case's model and compute its row (a minute or two)."""
    from dss14_env.core.schema import read_config
    from dss14_env.core.units import AXES
    from dss14_env.envs.plant import PlantFactory
    from dss14_env.model.analysis import dc_gain
    from dss14_env.model.assembly import default_model
    from dss14_env.wind.loads import (
        WindCalibrationError,
        calibrate_wind_loads,
        default_wind_loads,
        three_sigma_mdeg,
    )

    shipped, _ = read_config("model")
    u = 50 / 3.6

    def figures(model, loads) -> tuple[list[float], list[float]]:
        pl = model.position_loop("kp1")
        comp = [abs(dc_gain(model.rate_loop, f"enc_rate_{ax}", f"Tw_{ax}")) for ax in AXES]
        return comp, [float(three_sigma_mdeg(pl, loads, u, "front")[1]),
                      float(three_sigma_mdeg(pl, loads, u, "side")[0])]

    c0, s0 = figures(default_model(), default_wind_loads())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, values in cases(shipped):
            data = copy.deepcopy(shipped)
            for key, v in values.items():
                b, n = key.split(".")
                data[b][n]["value"] = float(v)
            path = Path(tmp) / "model.yaml"
            path.write_text(yaml.safe_dump(data), encoding="utf-8")
            f = PlantFactory.from_model_config(path)
            comp, sig = figures(f.model, f.loads)
            try:
                calibrate_wind_loads(f.model)
                refit = True
            except WindCalibrationError:
                refit = False
            rows.append({"case": label, "values": values,
                         "compliance_ratio_az_el": [comp[0] / c0[0], comp[1] / c0[1]],
                         "three_sigma_mdeg_el_front": sig[0], "three_sigma_mdeg_az_side": sig[1],
                         "refit_meets_table4": refit})
    return {"nominal": {"compliance_rad_s_per_Nm_az_el": c0, "three_sigma_mdeg_el_front": s0[0],
                        "three_sigma_mdeg_az_side": s0[1]},
            "note": "shipped wind-load coefficients; exact 3-sigma at 50 km/h, PI kp 1 ki 0.3",
            "rows": rows}


def render(res: dict) -> str:
    """The Markdown table of :func:`compute`'s result."""
    n = res["nominal"]
    lines = ["| user model (one range end, the rest shipped) | compliance az / el, × shipped | "
             "3σ el, front wind, mdeg | 3σ az, side wind, mdeg | exponent el / az | refit to Table 4 |",
             "|---|---|---|---|---|---|",
             f"| shipped model | 1 / 1 | {n['three_sigma_mdeg_el_front']:.2f} | "
             f"{n['three_sigma_mdeg_az_side']:.2f} | — | (the shipped fit) |"]
    for r in res["rows"]:
        ca, ce = r["compliance_ratio_az_el"]
        el, az = r["three_sigma_mdeg_el_front"], r["three_sigma_mdeg_az_side"]
        ex = []
        for s, s_nom, c in ((el, n["three_sigma_mdeg_el_front"], ce),
                            (az, n["three_sigma_mdeg_az_side"], ca)):
            ex.append("—" if abs(np.log(c)) < 0.05 else f"{np.log(s / s_nom) / np.log(c):.2f}")
        lines.append(f"| {r['case']} | {ca:.3g} / {ce:.3g} | {el:.2f} | {az:.2f} | {' / '.join(ex)} | "
                     f"{'meets it' if r['refit_meets_table4'] else '**misses it**'} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Compute (default), render or check."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_block_options(p, "docs/wind.md")
    a = p.parse_args(argv)
    if not (a.render or a.check):
        RESULTS.write_text(json.dumps(compute(), indent=1) + "\n", encoding="utf-8")
    return render_block(DOC, BLOCK, render(json.loads(RESULTS.read_text(encoding="utf-8"))), RESULTS,
                        "python scripts/wind_range_ends.py --render", check=a.check)


if __name__ == "__main__":
    sys.exit(main())
