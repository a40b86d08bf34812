"""The pointing bound with the monopulse sensor, at the default C/N0 and as a curve over C/N0.

For each carrier-to-noise density the monopulse sensor's jitter (:mod:`dss14_env.envs.monopulse`)
and, in 50 km/h front and side wind, the analytic rms pointing error of the loaded axis (el in
front wind, xel in side wind) of two references that measure the drive encoders AND the
monopulse sensor (:mod:`dss14_env.baselines.yardstick` with ``pointing_noise``):

* the pointing yardstick: the H2-optimal LQG for the benchmark's pointing cost (action-change
  weight 1), whatever acceleration it needs;
* the acceleration-matched reference: the same family with the action-change weight raised
  until its 3σ acceleration equals the command limiter's 0.2 deg/s^2.

The encoders-only figures (no monopulse) are the curve's floor reference.  Writes JSON::

    python scripts/monopulse_snr.py                          # docs/results/monopulse_snr.json
    python scripts/monopulse_snr.py --cnr 20 30 --out x.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from dss14_env.baselines.interface import ControlInterface
from dss14_env.baselines.monopulse import monopulse_noise
from dss14_env.baselines.yardstick import acceleration_matched, expected_performance
from dss14_env.core.units import KMH, MDEG
from dss14_env.envs.config import load_env_config
from dss14_env.envs.monopulse import MonopulseConstants

ROOT = Path(__file__).resolve().parents[1]
#: the curve's carrier-to-noise densities, dB-Hz
CNR_DBHZ = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
#: the sensor's keys written with the results
SENSOR_KEYS = ("monopulse_band", "monopulse_slope", "monopulse_bandwidth_hz", "monopulse_update_s",
               "monopulse_latency_s")
#: the wind directions and the axis each loads (index into [el, xel])
DIRECTIONS = {"front": ("el", 0), "side": ("xel", 1)}


def point(spec: ControlInterface, noise: float | None, iterations: int) -> dict:
    """The two references' loaded-axis rms pointing errors (mdeg) and accelerations per direction."""
    out = {}
    for d, (axis, i) in DIRECTIONS.items():
        y = expected_performance(spec, 50 * KMH, d, "pointing", pointing_noise=noise)
        m = acceleration_matched(spec, 50 * KMH, d, "pointing", iterations=iterations, pointing_noise=noise)
        out[d] = {"axis": axis, "yardstick_rms_mdeg": y["pointing_rms_mdeg"][i],
                  "yardstick_accel_3sigma_deg_s2": max(y["accel_three_sigma_deg_s2"]),
                  "matched_rms_mdeg": m["pointing_rms_mdeg"][i],
                  "matched_action_change": m["action_change"]}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cnr", type=float, nargs="+", default=list(CNR_DBHZ), help="C/N0 values, dB-Hz")
    ap.add_argument("--iterations", type=int, default=8,
                    help="bisection steps of the acceleration match (default 8: ~4 %% in the weight)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "results" / "monopulse_snr.json"))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    base = load_env_config(sensors=["encoders", "monopulse"])
    spec = ControlInterface.from_config(base)
    curve = []
    for cnr in [base.monopulse_cnr_dbhz, *args.cnr]:
        cfg = base.replace(monopulse_cnr_dbhz=cnr)
        k = MonopulseConstants.from_config(cfg)
        noise = monopulse_noise(cfg)
        row = {"cnr_dbhz": cnr, "jitter_rms_mdeg": k.sigma, "design_noise_mdeg": noise / MDEG,
               **point(spec, noise, args.iterations)}
        curve.append(row)
        f, s = row["front"]["matched_rms_mdeg"], row["side"]["matched_rms_mdeg"]
        print(f"{cnr:5.1f} dB-Hz: jitter {k.sigma:.4f} mdeg; front el {f:.3f}, side xel {s:.3f} mdeg rms "
              "(acceleration-matched)", flush=True)
    res = {"what": __doc__.split("\n\n")[0], "wind_speed_kmh": 50.0,
           "sensor": {k: getattr(base, k) for k in SENSOR_KEYS},
           "default_cnr_dbhz": base.monopulse_cnr_dbhz, "default": curve[0], "curve": curve[1:],
           "encoders_only": point(spec, None, args.iterations),
           "wall_time_s": time.perf_counter() - t0}
    Path(args.out).write_text(json.dumps(res, indent=1) + "\n")
    print(f"wrote {args.out} in {res['wall_time_s']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
