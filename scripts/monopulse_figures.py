"""The monopulse controllers' hold figures from a bench run: the loaded axis' rms pointing error
(mean included, pooled over the episodes as a root mean square), its ratio to the PI's and to
the acceleration-matched monopulse bound (``docs/results/monopulse_snr.json``), each with a
percentile-bootstrap 95 % interval over the episodes (paired with the PI's: the same seeds),
the acceleration-limit hits, and the wind envelope (``wind_envelope`` of results.json)::

    dss14 bench --controllers pi_kp1 lqg_pointing pi_monopulse lqg_monopulse \\
        --scenarios hold_front hold_side --episodes 16 --sweep-seeds 8 \\
        --wind-speeds 30 40 50 60 70 80 90 --out bench_monopulse
    python scripts/monopulse_figures.py bench_monopulse/results.json
    # docs/results/monopulse_holds.json and docs/results/ka_envelope.png
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: the hold scenarios, their direction in the bound's file and the axis the wind loads
HOLDS = {"hold_front": ("front", "el"), "hold_side": ("side", "xel")}
REFERENCE = "pi_kp1"


def column(episodes: dict, ctrl: str, scenario: str, key: str) -> np.ndarray:
    """One per-episode column of results.json (``{"same": v}`` for a constant one)."""
    v = episodes[ctrl][scenario][key]
    n = len(episodes[ctrl][scenario]["seed"])
    return np.full(n, v["same"], float) if isinstance(v, dict) else np.asarray(v, float)


def interval(x: np.ndarray) -> list[float]:
    return np.quantile(x, [0.025, 0.975]).tolist()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", help="a bench's results.json")
    ap.add_argument("--bound", default=str(ROOT / "docs" / "results" / "monopulse_snr.json"))
    ap.add_argument("--out", default=str(ROOT / "docs" / "results" / "monopulse_holds.json"))
    ap.add_argument("--resamples", type=int, default=4000)
    ap.add_argument("--figure", default=str(ROOT / "docs" / "results" / "ka_envelope.png"),
                    help="the envelope figure (empty: none)")
    args = ap.parse_args(argv)
    res = json.loads(Path(args.results).read_text())
    bound = json.loads(Path(args.bound).read_text())["default"]
    eps = res["episodes"]
    rng = np.random.default_rng(0)
    command = re.sub(r"--out \S+", "--out bench_monopulse", res["bench"]["command"])
    command = command.replace(" --overwrite", "")
    out: dict = {"command": command, "holds": {}, "envelope": res.get("wind_envelope")}
    for sc, (d, ax) in HOLDS.items():
        ref = column(eps, REFERENCE, sc, f"pointing_error_mdeg.{ax}.rms") ** 2
        b = bound[d]["matched_rms_mdeg"]
        rows = {}
        for c in eps:
            if sc not in eps[c]:
                continue
            ms = column(eps, c, sc, f"pointing_error_mdeg.{ax}.rms") ** 2
            idx = rng.integers(0, len(ms), (args.resamples, len(ms)))
            rms, rr = np.sqrt(ms[idx].mean(1)), np.sqrt(ref[idx].mean(1))
            steps = column(eps, c, sc, "n_steps").sum()
            hits = column(eps, c, sc, "limit_hits.accel").sum()
            value = float(np.sqrt(ms.mean()))
            rows[c] = {"rms_mdeg": value, "rms_ci95": interval(rms),
                       "vs_pi": value / float(np.sqrt(ref.mean())), "vs_pi_ci95": interval(rms / rr),
                       "vs_bound": value / b, "vs_bound_ci95": interval(rms / b),
                       "accel_limited_fraction": float(hits / steps), "episodes": len(ms)}
            print(f"{sc} {ax} {c:14s} rms {value:.3f} mdeg, ÷ PI {rows[c]['vs_pi']:.3f} "
                  f"[{rows[c]['vs_pi_ci95'][0]:.3f}, {rows[c]['vs_pi_ci95'][1]:.3f}], ÷ bound "
                  f"{rows[c]['vs_bound']:.2f}, acceleration limit {100 * hits / steps:.2f} % of the steps")
        out["holds"][sc] = {"axis": ax, "bound_rms_mdeg": b, "controllers": rows}
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")
    if out["envelope"] and args.figure:
        envelope_figure(out["envelope"], Path(args.figure))
        print(f"wrote {args.figure}")
    return 0


def envelope_figure(env: dict, path: Path) -> None:
    """The rms pointing error of the worse axis against the wind speed, per controller and
    direction, with the Ka and X requirements.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dirs = ("front", "side")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for a, d in zip(axes, dirs, strict=True):
        for c, bands in env["controllers"].items():
            cur = bands["Ka"].get(d)
            if cur:
                worst = np.maximum(cur["rms_mdeg"]["el"], cur["rms_mdeg"]["xel"])
                a.plot(cur["speeds_kmh"], worst, marker="o", label=c)
        for band, ls in (("Ka", "--"), ("X", ":")):
            req = env["requirements_rms_mdeg"][band]
            a.axhline(req, color="k", ls=ls, lw=1, label=f"{band} requirement ({req:.2f} mdeg rms per axis)")
        a.set_title(f"{d} wind")
        a.set_xlabel("mean wind speed (km/h)")
        a.set_yscale("log")
        a.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("rms pointing error, worse axis (mdeg)")
    axes[1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
