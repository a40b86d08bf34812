"""Where the pointing error lives: PSD and time history of the dish's cross-elevation pointing
error in 50 km/h side wind for the PI, the LQG and the pointing-aware LQG.

Each controller runs the same ``--episodes`` side-wind holds (``hold_side``, seeds 0, 1, ...;
60 s, the first 5 s left out) through the vector environment.  Per episode the xel pointing
error (mean removed) gives a Welch PSD (:func:`scipy.signal.welch`, Hann windows of
``--segment-s`` s, half overlap) and its rms in frequency bands; the figures are the mean PSD
over the episodes and the band rms pooled over episodes (root mean square) with a percentile
bootstrap 95 % interval over the episodes (:func:`dss14_env.core.stats.bootstrap_ci`).  The
time history is seed 0's.  Writes a PNG and a JSON (everything the figure shows plus the
options and the machine-independent inputs)::

    python scripts/pointing_psd.py --png docs/results/pointing_psd_side.png \\
        --json docs/results/pointing_psd_side.json
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
from collections.abc import Sequence

import numpy as np
from scipy import signal

from dss14_env.baselines.rollout import batch_driver
from dss14_env.bench.catalog import CONTROLLERS, SCENARIOS
from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.stats import bootstrap_ci
from dss14_env.envs.vector import DSS14VectorEnv

#: the controllers compared (catalog names)
DEFAULT_CONTROLLERS = ("pi_kp1", "lqg", "lqg_pointing")
#: frequency bands of the band rms, Hz (the rate loop's lightly damped poles are at 0.47 and
#: 0.69 Hz)
BANDS_HZ = ((0.0, 0.1), (0.1, 0.3), (0.3, 1.0), (1.0, 3.0), (3.0, 25.0))
SCENARIO = "hold_side"


def xel_errors(name: str, seeds: Sequence[int], seconds: float) -> tuple[np.ndarray, float]:
    """The xel pointing error (mdeg) ``(steps, episodes)`` of one controller over ``seconds``
    and the control period.
    """
    sc = SCENARIOS[SCENARIO].scenario()
    env = DSS14VectorEnv(num_envs=len(seeds), **sc.env)
    steps = int(round(seconds / env.config.dt))
    ctrl = CONTROLLERS[name].make(env)
    driver = batch_driver(ctrl)
    if driver is None:
        raise ValueError(f"{name} does not act on batches; this script runs batched controllers")
    obs, info = env.reset(seed=[int(s) for s in seeds])
    driver.reset(seeds, info)
    out = np.zeros((steps, len(seeds)))
    for k in range(steps):
        obs, _, term, _, info = env.step(driver.act(obs))
        if np.any(term):
            raise RuntimeError(f"{name}: an episode terminated at step {k}")
        out[k] = info["pointing_error_xel_mdeg"]
    return out, float(env.config.dt)


def band_rms(f: np.ndarray, psd: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """rms (mdeg) in ``[lo, hi)`` Hz of one-sided PSDs ``(..., len(f))`` (mdeg^2/Hz)."""
    m = (f >= lo) & (f < hi)
    df = f[1] - f[0]
    return np.sqrt(np.sum(psd[..., m], axis=-1) * df)


def analyse(x: np.ndarray, dt: float, warmup_s: float, segment_s: float) -> dict:
    """PSD and band rms of the episodes ``x`` ``(steps, episodes)`` after the warm-up."""
    y = x[int(round(warmup_s / dt)):]
    y = y - y.mean(axis=0)
    f, p = signal.welch(y.T, fs=1.0 / dt, nperseg=int(round(segment_s / dt)), axis=-1)
    rng = np.random.default_rng(0)
    bands = []
    for lo, hi in BANDS_HZ:
        per_ep = band_rms(f, p, lo, hi)
        est = bootstrap_ci(per_ep, lambda v: float(np.sqrt(np.mean(v ** 2))), rng)
        bands.append({"band_hz": [lo, hi], "rms_mdeg": est.as_dict(), "per_episode": per_ep.tolist()})
    sd = y.std(axis=0)
    three = bootstrap_ci(3 * sd, lambda v: float(np.sqrt(np.mean(v ** 2))), rng)
    return {"f_hz": f.tolist(), "psd_mdeg2_hz": p.mean(axis=0).tolist(), "bands": bands,
            "three_sigma_mdeg": three.as_dict()}


def plot(results: dict, png: str) -> None:
    """Two panels: mean PSD (log-log) with the rate-loop poles marked, and seed 0's history."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8.0, 7.0))
    for name, r in results["controllers"].items():
        f, p = np.array(r["f_hz"]), np.array(r["psd_mdeg2_hz"])
        t3 = r["three_sigma_mdeg"]
        ax1.loglog(f[1:], p[1:], label=f"{name}: 3σ {t3['value']:.2f} [{t3['ci95'][0]:.2f}, "
                                       f"{t3['ci95'][1]:.2f}] mdeg")
        t = np.arange(len(r["history_mdeg"])) * results["dt_s"]
        ax2.plot(t, r["history_mdeg"], lw=0.8, label=name)
    for fp in (0.47, 0.69):
        ax1.axvline(fp, color="0.6", ls=":", lw=1)
    ax1.set_xlabel("frequency (Hz)")
    ax1.set_ylabel("xel pointing error PSD (mdeg²/Hz)")
    ax1.set_title(f"50 km/h side wind: xel pointing error, mean of {results['episodes']} episodes "
                  "(dotted: rate-loop poles)")
    ax1.legend(fontsize=8)
    ax1.grid(True, which="both", alpha=0.3)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("xel pointing error (mdeg)")
    ax2.set_title("seed 0")
    ax2.legend(fontsize=8)
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=16, help="side-wind holds per controller (default 16)")
    p.add_argument("--seconds", type=float, default=60.0, help="episode length, s (default 60)")
    p.add_argument("--segment-s", type=float, default=20.0, help="Welch segment, s (default 20)")
    p.add_argument("--controllers", nargs="+", default=list(DEFAULT_CONTROLLERS), choices=sorted(CONTROLLERS))
    p.add_argument("--png", required=True, help="figure to write")
    p.add_argument("--json", required=True, help="figures to write")
    args = p.parse_args(argv)
    for path in (args.png, args.json):
        if not os.path.isdir(os.path.dirname(os.path.abspath(path))):
            p.error(f"folder of {path!r} does not exist")
    if args.episodes < 2 or args.seconds <= args.segment_s or args.segment_s <= 0:
        p.error("need --episodes >= 2 and 0 < --segment-s < --seconds")
    warmup = SCENARIOS[SCENARIO].scenario().warmup_s
    seeds = list(range(args.episodes))
    out = {"what": "xel pointing error in 50 km/h side wind (hold_side): Welch PSD, band rms, 3σ "
                   "(scripts/pointing_psd.py)",
           "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
           "options": vars(args), "scenario": SCENARIO, "warmup_s": warmup, "episodes": args.episodes,
           "statistics": "band rms and 3σ pooled over episodes (root mean square), percentile "
                         "bootstrap 95 % interval over episodes", "controllers": {}}
    for name in args.controllers:
        x, dt = xel_errors(name, seeds, args.seconds)
        r = analyse(x, dt, warmup, args.segment_s)
        r["history_mdeg"] = x[:, 0].tolist()
        out["controllers"][name] = r
        out["dt_s"] = dt
        bands = ", ".join(f"{b['band_hz'][0]}-{b['band_hz'][1]} Hz {b['rms_mdeg']['value']:.2f}"
                          for b in r["bands"])
        t3 = r["three_sigma_mdeg"]
        print(f"{name:>14s}: 3σ {t3['value']:.3f} mdeg [{t3['ci95'][0]:.3f}, {t3['ci95'][1]:.3f}]; "
              f"band rms {bands}")
    plot(out, args.png)
    atomic_write_text(args.json, json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.png} and {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
