"""The pointing LQG's ratio to the PI at 30, 50 and 70 km/h, analytic, for docs/results/notes.md.

``lqg_pointing`` is designed for the gust model at the design speed (50 km/h,
``design.wind_speed``) whatever the episode's wind.  This script asks why its ratio to the PI
is larger at 30 km/h than at 50 and 70, on one statistic: the stationary whole-record 3σ of
the linear closed loops (:func:`dss14_env.baselines.analysis.stationary_performance`) on the
full-order model in front and side wind, for

* the PI (kp 1) and the pointing LQG designed at 30, 50 (the shipped design) and 70 km/h, each
  with the wind's direction;
* the encoders as 20 bits per turn (quantisation as white noise, the design model's) and as
  exact, to separate the quantisation's share;
* beside them the bench's statistic in the environment (the PI and ``lqg_pointing``, 16 holds
  of 60 s per wind on seeds 1000-1015, which the bench does not use).

The loops are linear: no limiter, no true quantisation, the mean torque known.  Writes the JSON
and renders its table into docs/results/notes.md (region ``pointing-wind-speed``)::

    python scripts/pointing_wind_speed.py --json docs/results/pointing_wind_speed.json
    python scripts/pointing_wind_speed.py --render
    python scripts/pointing_wind_speed.py --check
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.text import add_block_options, render_block

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results" / "pointing_wind_speed.json"
DOC = ROOT / "docs" / "results" / "notes.md"
BLOCK = "pointing-wind-speed"
SPEEDS_KMH = (30.0, 50.0, 70.0)
#: the loaded pointing axis per wind direction (index into [el, xel])
DIRECTIONS = {"front": 0, "side": 1}
ENCODERS = {"20-bit": "config", "exact": None}
POINTING_AXES = ("el", "xel")
#: the simulated holds: 60 s each, on seeds the bench does not use
SIM_SEEDS = tuple(range(1000, 1016))
SIM_STEPS = 3000


def compute() -> dict[str, Any]:
    """Every row, analytic and simulated (a few minutes)."""
    from dss14_env.baselines.analysis import (
        closed_loop,
        lqg_as_linear,
        pi_as_linear,
        stationary_performance,
    )
    from dss14_env.baselines.design import build_design_model, default_controllers_config
    from dss14_env.baselines.interface import ControlInterface
    from dss14_env.baselines.lqg import lqg_design_from_config
    from dss14_env.core.units import KMH, R2D
    from dss14_env.wind.loads import direction_angle

    spec = ControlInterface.default()
    pointing = default_controllers_config().pointing
    rows = []
    for direction, axis in DIRECTIONS.items():
        designs = {v: lqg_design_from_config(spec, wind=(v * KMH, direction_angle(direction)),
                                             pointing=pointing) for v in SPEEDS_KMH}
        for enc, bits in ENCODERS.items():
            for v in SPEEDS_KMH:
                plant = build_design_model(spec.dt, order=None, wind=(v * KMH, direction), bits=bits,
                                           pointing=True)
                pi = stationary_performance(closed_loop(plant, pi_as_linear(spec.dt)), spec.weights)
                row = {"direction": direction, "encoders": enc, "speed_kmh": v,
                       "pi_mdeg": pi["pointing_three_sigma_mdeg"][axis], "lqg": {}}
                for dv, d in designs.items():
                    p = stationary_performance(closed_loop(plant, lqg_as_linear(d)), spec.weights)
                    row["lqg"][f"{dv:g}"] = {
                        "mdeg": p["pointing_three_sigma_mdeg"][axis],
                        "accel_deg_s2": 3.0 * max(p["command_change_rms_rad_s"]) / spec.dt * R2D}
                rows.append(row)
    return {"simulated": simulated(),
            "what": "pointing 3σ on the loaded axis (front el, side xel), stationary whole-record, "
                    "linear closed loops on the full-order model; lqg_pointing designed at 30, 50 "
                    "(shipped), 70 km/h",
            "accel_limit_deg_s2": spec.accel_limit * R2D, "rows": rows}


def simulated() -> dict[str, Any]:
    """The bench's statistic on seeds outside the bench's (:data:`SIM_SEEDS`): pooled 3σ and the
    ratio to the PI paired on the seeds, with percentile-bootstrap 95 % intervals, per wind."""
    from dss14_env.bench.plan import sweep_name, sweep_scenario
    from dss14_env.bench.runner import run

    scen = [(sweep_name(d, v), sweep_scenario(d, v, SIM_STEPS)) for d in DIRECTIONS for v in SPEEDS_KMH]
    res = run(["pi_kp1", "lqg_pointing"], scen, seeds=SIM_SEEDS, reference="pi_kp1")
    out = {}
    for (name, _), (d, v) in zip(scen, [(d, v) for d in DIRECTIONS for v in SPEEDS_KMH], strict=True):
        ax = POINTING_AXES[DIRECTIONS[d]]
        cell = res["summary"]["lqg_pointing"][name]
        out[name] = {"direction": d, "speed_kmh": v, "axis": ax,
                     "pi_mdeg": res["summary"]["pi_kp1"][name]["pointing_error_mdeg"][ax]["three_sigma"],
                     "lqg_pointing_mdeg": cell["pointing_error_mdeg"][ax]["three_sigma"],
                     "ratio": cell["vs_reference_pointing_error_mdeg"][ax]}
    return {"seeds": list(SIM_SEEDS), "steps": SIM_STEPS, "cells": out}


def render(res: dict[str, Any]) -> str:
    """The Markdown table of :func:`compute`'s result."""
    designs = [f"{v:g}" for v in SPEEDS_KMH]
    head = " | ".join(f"designed at {d} km/h: ÷ PI (accel. °/s²)" for d in designs)
    lines = [f"| wind | encoders | speed, km/h | PI 3σ, mdeg | {head} |",
             "|---|---|---|---|" + "---|" * len(designs)]
    for r in res["rows"]:
        cells = " | ".join(f"{r['lqg'][d]['mdeg'] / r['pi_mdeg']:.3f} ({r['lqg'][d]['accel_deg_s2']:.2f})"
                           for d in designs)
        lines.append(f"| {r['direction']} | {r['encoders']} | {r['speed_kmh']:g} | {r['pi_mdeg']:.3f} | "
                     f"{cells} |")
    sim = res["simulated"]
    lines += ["", f"Simulated (the environment: 20-bit encoders, limiter; {len(sim['seeds'])} holds of "
              f"{sim['steps'] // 50} s on seeds {sim['seeds'][0]}–{sim['seeds'][-1]}, pooled 3σ about each "
              "episode's mean, ratio paired on the seeds, 95 % intervals):", "",
              "| wind | speed, km/h | PI 3σ, mdeg | lqg_pointing 3σ, mdeg | ÷ PI |", "|---|---|---|---|---|"]
    for c in sim["cells"].values():
        r = c["ratio"]
        lines.append(f"| {c['direction']} ({c['axis']}) | {c['speed_kmh']:g} | {c['pi_mdeg']['value']:.3f} | "
                     f"{c['lqg_pointing_mdeg']['value']:.3f} | {r['value']:.3f} [{r['ci95'][0]:.3f}, "
                     f"{r['ci95'][1]:.3f}] |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Compute (``--json``), render or check."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_block_options(p, "docs/results/notes.md", ("--json", "compute and write this file, then render"))
    a = p.parse_args(argv)
    if a.json:
        atomic_write_text(a.json, json.dumps(compute(), indent=1) + "\n")
    source = Path(a.json) if a.json else RESULTS
    return render_block(DOC, BLOCK, render(json.loads(source.read_text())), source,
                        "python scripts/pointing_wind_speed.py --render", check=a.check)


if __name__ == "__main__":
    sys.exit(main())
