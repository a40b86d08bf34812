"""The controllers' measured figures with 95 % intervals, for docs/controllers.md.

Runs the one runner (:func:`dss14_env.bench.runner.run`) on the benchmark scenarios and on
randomised hydraulics, and writes what docs/controllers.md §7 quotes::

    python scripts/controller_figures.py --json docs/results/controller_figures.json \\
        --markdown docs/results/controller_figures.md

The unit of every statistic is the episode (its own seed: start, wind, gusts, trajectory and,
randomised, the plant).  Per controller and scenario: the median over episodes of the 3-sigma
servo error of each axis with a percentile bootstrap 95 % interval, and ratios to the PI
(kp 1) and to the simulated yardstick paired by seed (:func:`dss14_env.core.stats.ratio_ci`;
"n.s." where the interval contains 1).  The figures are simulations with seeded generators: the
same on any machine up to floating-point rounding.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence

import numpy as np

from dss14_env.bench.runner import run
from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.stats import bootstrap_ci, ratio_ci
from dss14_env.core.units import AXES

#: dominant axis of each windy scenario: the one the wind loads
DOMINANT = {"hold_front": "el", "hold_side": "az"}


def _values(episodes: list[dict], ctrl: str, scenario: str, get) -> np.ndarray:
    eps = sorted(
        (e for e in episodes if e["controller"] == ctrl and e["scenario"] == scenario),
        key=lambda e: e["seed"],
    )
    return np.array([get(e) for e in eps], float)


def _est(x: np.ndarray) -> dict:
    return bootstrap_ci(x, np.median, np.random.default_rng(0)).as_dict()


def _ratio(num: np.ndarray, den: np.ndarray) -> dict:
    return ratio_ci(num, den, np.median, np.random.default_rng(1), paired=True).as_dict()


def figures(episodes: list[dict], controllers: Sequence[str], scenarios: Sequence[str]) -> dict:
    """Per controller and scenario: 3-sigma per axis, ratios on the dominant axis, step and
    command metrics, limiter hits, fallbacks."""
    out: dict = {}
    for sc in scenarios:
        for c in controllers:
            if not any(e["controller"] == c and e["scenario"] == sc for e in episodes):
                continue
            three = {
                ax: _values(episodes, c, sc, lambda e, ax=ax: e["servo_error_mdeg"][ax]["three_sigma"])
                for ax in AXES
            }
            row: dict = {
                "three_sigma_mdeg": {ax: _est(v) for ax, v in three.items()},
                "max_error_mdeg": {
                    ax: float(
                        _values(episodes, c, sc, lambda e, ax=ax: e["servo_error_mdeg"][ax]["max"]).max()
                    )
                    for ax in AXES
                },
                "limit_hits": int(_values(episodes, c, sc, lambda e: sum(e["limit_hits"].values())).sum()),
                "fallbacks": int(_values(episodes, c, sc, lambda e: e["fallbacks"]).sum()),
                "terminated": int(_values(episodes, c, sc, lambda e: e["terminated"]).sum()),
                "n_episodes": int(three["az"].size),
            }
            if sc in DOMINANT:
                ax = DOMINANT[sc]
                for ref in ("pi_kp1", "yardstick"):
                    if ref != c and ref in controllers:
                        den = _values(
                            episodes, ref, sc, lambda e, ax=ax: e["servo_error_mdeg"][ax]["three_sigma"]
                        )
                        if den.size == three[ax].size:
                            row[f"ratio_to_{ref}"] = _ratio(three[ax], den)
            if sc == "step":
                row["step"] = {
                    ax: {
                        k: _est(_values(episodes, c, sc, lambda e, ax=ax, k=k: e["step"][ax][k]))
                        for k in ("overshoot_pct", "settling_time_s")
                    }
                    for ax in AXES
                }
            if sc == "slew":
                row["peak_rate_deg_s"] = {
                    ax: float(
                        _values(episodes, c, sc, lambda e, ax=ax: e["rate_command_deg_s"][ax]["peak"]).max()
                    )
                    for ax in AXES
                }
                row["peak_accel_deg_s2"] = {
                    ax: float(
                        _values(
                            episodes, c, sc, lambda e, ax=ax: e["rate_command_deg_s"][ax]["peak_accel_deg_s2"]
                        ).max()
                    )
                    for ax in AXES
                }
            if "randomised" in sc:
                ax = DOMINANT[sc.split("/")[0]]
                v = three[ax]
                row["dominant_spread_mdeg"] = {
                    "median": float(np.median(v)),
                    "p90": float(np.percentile(v, 90)),
                    "worst": float(v.max()),
                    "worst_seed": int(np.argmax(v)),
                }
            out.setdefault(sc, {})[c] = row
    return out


def _fmt(e: dict, digits: int = 3) -> str:
    return f"{e['value']:.{digits}g} [{e['ci95'][0]:.{digits}g}, {e['ci95'][1]:.{digits}g}]"


def markdown(doc: dict) -> str:
    """The tables docs/controllers.md points to (generated, not typed)."""
    f = doc["figures"]
    lines = [
        "# Controllers: measured figures (generated by scripts/controller_figures.py)",
        "",
        f"Episodes: {doc['options']['seeds']} seeds per scenario; randomised hydraulics: "
        f"{doc['options']['random_seeds']} seeds.  Values: median over episodes [95 % percentile "
        "bootstrap interval over episodes]; ratios paired by seed, n.s. = interval contains 1.",
        "",
    ]
    for sc in [s for s in f if s in DOMINANT or "randomised" in s]:
        ax = DOMINANT[sc.split("/")[0]]
        lines += [
            f"## {sc} (dominant axis {ax})",
            "",
            "| controller | 3σ az (mdeg) | 3σ el (mdeg) | ÷ PI kp 1 | ÷ simulated yardstick | limiter hits | "
            "fallbacks | terminated |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for c, r in f[sc].items():
            rat = []
            for ref in ("pi_kp1", "yardstick"):
                q = r.get(f"ratio_to_{ref}")
                rat.append("—" if q is None else _fmt(q) + ("" if q["significant"] else " n.s."))
            lines.append(
                f"| {c} | {_fmt(r['three_sigma_mdeg']['az'])} | {_fmt(r['three_sigma_mdeg']['el'])} | "
                f"{rat[0]} | {rat[1]} | {r['limit_hits']} | {r['fallbacks']} | {r['terminated']} |"
            )
        if "randomised" in sc:
            lines += [
                "",
                "| controller | dominant 3σ median / p90 / worst (mdeg) | worst seed | max error (mdeg) |",
                "|---|---|---|---|",
            ]
            for c, r in f[sc].items():
                s = r["dominant_spread_mdeg"]
                lines.append(
                    f"| {c} | {s['median']:.3g} / {s['p90']:.3g} / {s['worst']:.3g} | {s['worst_seed']} | "
                    f"{max(r['max_error_mdeg'].values()):.3g} |"
                )
        lines.append("")
    if "step" in f:
        lines += [
            "## step (0.1° on both axes at 1 s, no wind)",
            "",
            "| controller | overshoot az / el (%) | 2 % settling az / el (s) | limiter hits | fallbacks |",
            "|---|---|---|---|---|",
        ]
        for c, r in f["step"].items():
            st = r["step"]
            lines.append(
                f"| {c} | {_fmt(st['az']['overshoot_pct'])} / {_fmt(st['el']['overshoot_pct'])} | "
                f"{_fmt(st['az']['settling_time_s'])} / {_fmt(st['el']['settling_time_s'])} | "
                f"{r['limit_hits']} | {r['fallbacks']} |"
            )
        lines.append("")
    for sc, title in (("slew", "slew (5°, 30 km/h)"), ("track", "track (random 30–70 km/h and direction)")):
        if sc not in f:
            continue
        lines += [
            f"## {title}",
            "",
            "| controller | 3σ az (mdeg) | 3σ el (mdeg) | max error az / el (mdeg) | "
            "peak rate az / el (°/s) | peak command accel. az / el (°/s²) | limiter hits | fallbacks |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for c, r in f[sc].items():
            pr, pa = r.get("peak_rate_deg_s"), r.get("peak_accel_deg_s2")
            lines.append(
                f"| {c} | {_fmt(r['three_sigma_mdeg']['az'])} | {_fmt(r['three_sigma_mdeg']['el'])} | "
                f"{r['max_error_mdeg']['az']:.3g} / {r['max_error_mdeg']['el']:.3g} | "
                + (f"{pr['az']:.3f} / {pr['el']:.3f} | {pa['az']:.3f} / {pa['el']:.3f}" if pr else "— | —")
                + f" | {r['limit_hits']} | {r['fallbacks']} |"
            )
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=5, help="episodes per scenario (seeds 0..n-1, default 5)")
    p.add_argument(
        "--random-seeds", type=int, default=20, help="episodes on randomised hydraulics (default 20)"
    )
    p.add_argument("--steps", type=int, default=None, help="override every scenario's episode length")
    p.add_argument("--json", metavar="FILE", required=True)
    p.add_argument("--markdown", metavar="FILE", required=True)
    args = p.parse_args(argv)
    for path in (args.json, args.markdown):
        if not os.path.isdir(os.path.dirname(os.path.abspath(path))):
            p.error(f"folder of {path!r} does not exist")
    t0 = time.perf_counter()
    seeds = list(range(args.seeds))
    ctrls = ["pi_kp1", "pi_kp0.7", "lqg", "mpc"]
    hold = run(ctrls + ["yardstick"], ["hold_front", "hold_side"], seeds, steps=args.steps)
    moves = run(ctrls, ["step", "slew", "track"], seeds, steps=args.steps)
    rnd = run(
        ["pi_kp1", "lqg", "mpc"],
        ["hold_front", "hold_side"],
        list(range(args.random_seeds)),
        env_kwargs={"randomize_params": True},
        steps=args.steps,
    )
    for e in rnd["episodes"]:
        e["scenario"] += "/randomised"
    episodes = hold["episodes"] + moves["episodes"] + rnd["episodes"]
    scen = [
        "hold_front",
        "hold_side",
        "step",
        "slew",
        "track",
        "hold_front/randomised",
        "hold_side/randomised",
    ]
    doc = {
        "what": "controller figures of docs/controllers.md (scripts/controller_figures.py)",
        "options": {"seeds": seeds, "random_seeds": list(range(args.random_seeds)), "steps": args.steps},
        "yardstick_analytic": hold["yardstick"],
        "figures": figures(episodes, ctrls + ["yardstick"], scen),
        "wall_time_s": time.perf_counter() - t0,
    }
    atomic_write_text(args.json, json.dumps(doc, indent=1) + "\n")
    atomic_write_text(args.markdown, markdown(doc) + "\n")
    print(markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
