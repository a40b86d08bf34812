"""The figures behind ``lqg_pointing_sched``'s schedule and its limits, written to
``docs/results/light_wind.json`` (read in ``docs/results/light_wind.md``):

* ``noise_sweep``: the schedule's measurement noise at the 10-, 20- and 30-km/h grid points,
  30-s holds from the front and the side on seeds 1000-1015 (not the grid's 0-63): the
  pointing 3σ of the report's PI and of the scheduled LQG with 0.1, 0.3 and 0.7 mdeg;
* ``quantisation``: the 10-km/h grid points (seeds 0-63, 30 s) with the shipped 20-bit
  encoders and with exact ones (``encoder_bits=None``): the PI, the scheduled LQG and the
  pointing yardstick (the full-order LQG designed for the episode's exact wind);
* ``moves``: acceleration-limit hits per episode in the bench's slew and step (seeds 0-31):
  the PI, ``lqg_pointing`` and the scheduled LQG.

About a minute and a half of CPU (one core)::

    python scripts/light_wind_figures.py
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.baselines.design import default_controllers_config
from dss14_env.baselines.scheduled import ScheduledPointingLQGController
from dss14_env.bench import runner
from dss14_env.bench.grid import grid_scenario
from dss14_env.bench.report import package_versions, results_json
from dss14_env.bench.threads import blas_threads
from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.results import POINTING, POINTING_AXES
from dss14_env.core.units import MDEG

OUT = Path(__file__).resolve().parents[1] / "docs" / "results" / "light_wind.json"
SWEEP_NOISE_MDEG = (0.1, 0.3, 0.7)


def _pointing(res: dict[str, Any]) -> dict[str, Any]:
    """Per scenario and controller: the pooled 3σ (el, xel, mdeg) and the ratio to the PI."""
    out: dict[str, Any] = {}
    for c, cells in res["summary"].items():
        for s, cell in cells.items():
            r = cell.get("vs_reference_pointing_error_mdeg", {})
            out.setdefault(s, {})[c] = {
                "three_sigma_mdeg": {ax: cell[POINTING][ax]["three_sigma"]["value"] for ax in POINTING_AXES},
                "vs_pi": {ax: {"value": r[ax]["value"], "ci95": r[ax]["ci95"]} for ax in r}}
    return out


def _noise_sweep() -> dict[str, Any]:
    cfg = default_controllers_config()
    sched = cfg.schedule

    def make(noise: float) -> Any:
        sc = dataclasses.replace(sched, measurement_noise=(noise * MDEG,) * len(sched.wind_speeds))
        return lambda env: ScheduledPointingLQGController(env, schedule=sc)

    ctrls = ["pi_kp1"] + [(f"sched_{n:g}mdeg", make(n)) for n in SWEEP_NOISE_MDEG]
    scens = [(f"hold_{d}deg_{v}kmh", grid_scenario(d, v, 30.0)) for v in (10, 20, 30) for d in (0, 90)]
    return _pointing(runner.run(ctrls, scens, range(1000, 1016)))


def _quantisation() -> dict[str, Any]:
    scens = [(f"hold_{d}deg_10kmh", grid_scenario(d, 10, 30.0)) for d in (0, 90)]
    ctrls = ["pi_kp1", "lqg_pointing_sched", "yardstick_pointing"]
    return {label: _pointing(runner.run(ctrls, scens, range(64), env_kwargs=kw))
            for label, kw in (("20_bit", {}), ("exact", {"encoder_bits": None}))}


def _moves() -> dict[str, Any]:
    res = runner.run(["pi_kp1", "lqg_pointing", "lqg_pointing_sched"], ["slew", "step"], range(32))
    out: dict[str, Any] = {}
    for e in res["episodes"]:
        out.setdefault(e["scenario"], {}).setdefault(e["controller"], []).append(e["limit_hits"]["accel"])
    return {s: {c: {"accel_hits_per_episode": float(np.mean(h)), "min": int(min(h)), "max": int(max(h)),
                    "episodes": len(h)} for c, h in cs.items()} for s, cs in out.items()}


def main() -> int:
    t0 = time.perf_counter()
    with blas_threads(1):
        results = {"noise_sweep": _noise_sweep(), "quantisation": _quantisation(), "moves": _moves()}
    results["meta"] = {"command": "python scripts/light_wind_figures.py", "versions": package_versions(),
                       "wall_time_s": time.perf_counter() - t0}
    atomic_write_text(OUT, results_json(results))
    print(f"{OUT} written; wall time {results['meta']['wall_time_s']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
