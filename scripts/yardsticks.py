"""The two yardsticks and their 3σ references, analytic and simulated, for docs/controllers.md.

For 50 km/h front and side wind on the drive encoders (the shipped environment), every figure
analytic (Riccati + Lyapunov, :mod:`dss14_env.baselines.yardstick`) unless said:

* the encoder yardstick (H2-optimal for ``J_enc``, the benchmark's weight ``w``), its error-only
  limit (``w -> 0``) and its acceleration-matched design (largest 3σ acceleration = the
  limiter's 0.2 deg/s^2), the design with ``w`` x 1e-3 (what the yardstick does not bound);
* the same three for the pointing yardstick (``J_point``);
* the sampled kp 1 PI on the same model and wind, with the same statistic (stationary
  whole-record 3σ), the denominator of the table's ratios;
* the simulated yardsticks (``YardstickController``, ``PointingYardstickController``): pooled
  3σ with percentile bootstrap 95 % intervals over ``--episodes`` holds of 60 s, on the
  shipped environment (20-bit encoders, limiter) and on the model's own problem (24-bit
  encoders, whose quantisation is near white, limiter opened).

Writes the JSON and renders its table into docs/controllers.md (region ``yardsticks``)::

    python scripts/yardsticks.py --json docs/results/yardsticks.json   # measure, write, render
    python scripts/yardsticks.py --render                               # render the committed file
    python scripts/yardsticks.py --check                                # exit 1 if the doc differs
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path
from typing import Any

from dss14_env.baselines.interface import ControlInterface
from dss14_env.baselines.yardstick import (
    ERROR_ONLY_WEIGHT,
    PointingYardstickController,
    YardstickController,
    acceleration_matched,
    error_only_limit,
    expected_performance,
    pi_performance,
)
from dss14_env.bench.runner import run
from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.text import add_block_options, render_block
from dss14_env.core.units import KMH, R2D

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results" / "yardsticks.json"
DOC = ROOT / "docs" / "controllers.md"
REGION = "yardsticks"
SPEED_KMH = 50.0
DIRECTIONS = {"front": "hold_front", "side": "hold_side"}
#: the simulated settings: the shipped environment and the model's own problem
SIM_SETTINGS = {"shipped (20-bit, limiter)": {},
                "model's problem (24-bit, no limiter)": {"encoder_bits": 24, "accel_limit_deg_s2": 100.0}}
#: the PI row of the analytic table: the sampled kp 1 PI on the yardsticks' model and wind
PI_DESIGN = "PI kp 1 (sampled)"
KEYS = ("action_change", "three_sigma_mdeg", "pointing_three_sigma_mdeg", "accel_three_sigma_deg_s2",
        "cost", "cost_pointing")


def analytic_rows(spec: ControlInterface, direction: str) -> list[dict[str, Any]]:
    """The analytic designs of one wind (see the module docstring)."""
    U = SPEED_KMH * KMH
    rows = []
    for error in ("encoder", "pointing"):
        for label, perf in (("benchmark weight (the yardstick)",
                             expected_performance(spec, U, direction, error)),
                            ("weight x 1e-3", expected_performance(spec, U, direction, error, 1e-3)),
                            (f"error-only limit (weight x {ERROR_ONLY_WEIGHT:g})",
                             error_only_limit(spec, U, direction, error)),
                            ("acceleration-matched", acceleration_matched(spec, U, direction, error))):
            rows.append({"error": error, "design": label, **{k: perf[k] for k in KEYS}})
    pi = pi_performance(spec, U, direction)
    rows.append({"error": "pi", "design": PI_DESIGN, **{k: pi[k] for k in KEYS}})
    return rows


def pi_row(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The PI's row of one wind's analytic rows (the denominator of the ratios)."""
    return next(r for r in rows if r["error"] == "pi")


def simulated(episodes: int) -> dict[str, Any]:
    """Pooled 3σ of the simulated yardsticks per setting, controller and scenario."""
    out: dict[str, Any] = {}
    ctrls = [("yardstick", YardstickController), ("yardstick_pointing", PointingYardstickController)]
    for name, kw in SIM_SETTINGS.items():
        res = run(ctrls, list(DIRECTIONS.values()), seeds=list(range(episodes)), env_kwargs=kw,
                  reference=None)
        out[name] = {"env_kwargs": kw, "cells": {
            c: {s: {q: {ax: v["three_sigma"] for ax, v in cell[q].items()}
                    for q in ("servo_error_mdeg", "pointing_error_mdeg")} | {
                    "accel_hits_per_episode": cell["limit_hits"]["per_episode"]["accel"]["value"]}
                for s, cell in per.items()} for c, per in res["summary"].items()},
            "analytic": {s: {"encoder": y["three_sigma_mdeg"],
                             "pointing": y["pointing"]["pointing_three_sigma_mdeg"]}
                         for s, y in res["yardstick"].items()}}
    return out


def _f(x: float | None) -> str:
    if x is None:  # no such figure (the PI has no action-change weight)
        return "—"
    return f"{x:.3g}" if abs(x) < 100 else f"{x:.0f}"


def _ci(c: dict) -> str:
    return f"{c['value']:.3f} [{c['ci95'][0]:.3f}, {c['ci95'][1]:.3f}]"


def render(doc: dict) -> str:
    """The markdown of the region: the analytic table and the simulated table."""
    lines = ["Analytic, 50 km/h, drive encoders (20-bit); 3σ in mdeg, acceleration 3σ in °/s² "
             f"(limit {doc['accel_limit_deg_s2']:g}); J per step. Every figure, the PI's too, is the "
             "stationary whole-record 3σ of the linear closed loop on the yardsticks' full-order model "
             "(quantisation as white noise, no limiter), so the ratio to the PI is on one statistic:", "",
             "| wind | cost | design | weight × | servo 3σ az / el | pointing 3σ el / xel | "
             "pointing 3σ ÷ PI el / xel | acceleration 3σ az / el | J_enc | J_point |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for d, rows in doc["analytic"].items():
        pi = pi_row(rows)["pointing_three_sigma_mdeg"]
        for r in rows:
            lines.append(f"| {d} | {r['error']} | {r['design']} | {_f(r['action_change'])} | "
                         + " / ".join(_f(x) for x in r["three_sigma_mdeg"]) + " | "
                         + " / ".join(_f(x) for x in r["pointing_three_sigma_mdeg"]) + " | "
                         + " / ".join(f"{x / p:.3f}" for x, p in zip(r["pointing_three_sigma_mdeg"], pi,
                                                                     strict=True)) + " | "
                         + " / ".join(_f(x) for x in r["accel_three_sigma_deg_s2"])
                         + f" | {r['cost']:.3g} | {r['cost_pointing']:.3g} |")
    lines += ["", f"Simulated ({doc['episodes']} holds of 60 s, pooled 3σ with 95 % interval) against "
              "the analytic value of the same setting, on the loaded axis:", "",
              "| setting | yardstick | wind | simulated 3σ | analytic | accel. limit hits / episode |",
              "|---|---|---|---|---|---|"]
    for setting, v in doc["simulated"].items():
        for c, per in v["cells"].items():
            for d, s in DIRECTIONS.items():
                if c == "yardstick":
                    ax, i, q, key = ("el", 1, "servo_error_mdeg", "encoder") if d == "front" else \
                        ("az", 0, "servo_error_mdeg", "encoder")
                else:
                    ax, i, q, key = ("el", 0, "pointing_error_mdeg", "pointing") if d == "front" else \
                        ("xel", 1, "pointing_error_mdeg", "pointing")
                what = "servo" if key == "encoder" else "pointing"
                lines.append(f"| {setting} | {c} | {d} | {what} {ax} {_ci(per[s][q][ax])} | "
                             f"{v['analytic'][s][key][i]:.3f} | {per[s]['accel_hits_per_episode']:.1f} |")
    return "\n".join(lines) + "\n"


def write_doc(doc: dict, source: Path, check: bool) -> int:
    """Render ``doc`` (read from ``source``) into docs/controllers.md (or check it); 1 when the
    check fails.
    """
    return render_block(DOC, REGION, render(doc), source, "python scripts/yardsticks.py --render",
                        check=check)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_block_options(p, "docs/controllers.md", ("--json", "measure and write this file, then render"))
    p.add_argument("--episodes", type=int, default=16, help="simulated holds per setting (default 16)")
    args = p.parse_args(argv)
    if args.json:
        spec = ControlInterface.default()
        doc = {"what": "the encoder and pointing yardsticks at 50 km/h: analytic references and "
                       "simulated yardsticks (scripts/yardsticks.py)",
               "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
               "speed_kmh": SPEED_KMH, "accel_limit_deg_s2": spec.accel_limit * R2D,
               "episodes": args.episodes,
               "statistics": "simulated: pooled 3σ (rms of the episodes' 3σ), percentile bootstrap 95 % "
                             "interval over episodes",
               "analytic": {d: analytic_rows(spec, d) for d in DIRECTIONS},
               "simulated": simulated(args.episodes)}
        atomic_write_text(args.json, json.dumps(doc, indent=1) + "\n")
        print(f"wrote {args.json}")
        return write_doc(doc, Path(args.json), check=False)
    return write_doc(json.loads(RESULTS.read_text()), RESULTS, check=args.check)


if __name__ == "__main__":
    sys.exit(main())
