"""Do two bench runs agree within their confidence intervals?

Compares every pooled figure with an interval (3σ, rms, peaks of the servo and pointing
errors, command rates, limiter hits, step responses; not the wall-clock timings) of two
results.json files of the same plan, e.g. a default run with 1 and one with 2 BLAS threads::

    dss14 bench --threads 1 --out run1 && dss14 bench --threads 2 --out run2
    python scripts/compare_bench_runs.py run1/results.json run2/results.json

A figure agrees when each run's value lies inside the other run's 95 % interval.  Prints, for
the loaded axis' figures of the hold scenarios and the sweep (3σ and its ratios), for all the
tables' figures (3σ of both axes in every scenario and sweep point, the ratios) and for all
pooled figures, how many were compared, the largest difference in units of the intervals'
half-widths, and every figure that does not agree; exits 1 if a loaded-axis figure does not.

Two runs that differ only in the last bits of their arithmetic see the same gusts, so their
figures differ far less than two independent replicates would (for which about 17 % of the
values fall outside the other's 95 % interval, the difference of two equal, independent
estimates having sqrt(2) times their spread).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def figures(summary: dict[str, Any], prefix: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], dict]]:
    """Every ``{"value", "ci95", ...}`` cell of a summary, by its key path (timings left out)."""
    for k, v in summary.items():
        if not isinstance(v, dict) or k == "controller_time_ms":
            continue
        if "value" in v and "ci95" in v:
            yield prefix + (k,), v
        else:
            yield from figures(v, prefix + (k,))


def _finite(*x: Any) -> bool:
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in x)


def is_table_figure(path: tuple[str, ...]) -> bool:
    """The figures of the tables: 3σ servo errors and the ratios."""
    return (len(path) == 6 and path[3] == "servo_error_mdeg" and path[5] == "three_sigma") or (
        len(path) == 5 and path[3] in ("vs_reference", "vs_yardstick"))


def is_loaded_figure(path: tuple[str, ...]) -> bool:
    """A table figure of the axis the wind loads in a hold scenario or sweep point (front wind:
    el, side wind: az): the precision target's figures.  Paths are (main|sweep, controller,
    scenario, metric, axis[, statistic])."""
    if not is_table_figure(path):
        return False
    scenario, axis = path[2], path[4]
    return (scenario.startswith("hold_front") and axis == "el") or (
        scenario.startswith("hold_side") and axis == "az")


CATEGORIES = {"loaded-axis figures of the hold scenarios and the sweep (3σ and ratios)": is_loaded_figure,
              "table figures (3σ and ratios, both axes, every scenario)": is_table_figure,
              "all pooled figures": lambda path: True}


def name(path: tuple[str, ...]) -> str:
    return "/".join(path)


def compare(a: dict[str, Any], b: dict[str, Any], keep: Any = None) -> dict[str, Any]:
    """Agreement of the main summaries and the sweep summaries of two results (the figures
    whose path ``keep`` accepts; default all)."""
    cells_a = dict(figures({"main": a["summary"], "sweep": (a.get("wind_sweep") or {}).get("summary", {})}))
    cells_b = dict(figures({"main": b["summary"], "sweep": (b.get("wind_sweep") or {}).get("summary", {})}))
    common = sorted(p for p in set(cells_a) & set(cells_b) if keep is None or keep(p))
    worst, bad, n, identical = 0.0, [], 0, 0
    for path in common:
        x, y = cells_a[path], cells_b[path]
        (lo_a, hi_a), (lo_b, hi_b) = x["ci95"], y["ci95"]
        if not _finite(x["value"], y["value"], lo_a, hi_a, lo_b, hi_b):
            continue
        n += 1
        identical += x["value"] == y["value"]
        ok = lo_a <= y["value"] <= hi_a and lo_b <= x["value"] <= hi_b
        hw = 0.5 * max(hi_a - lo_a, hi_b - lo_b)
        r = abs(x["value"] - y["value"]) / hw if hw > 0 else (0.0 if x["value"] == y["value"] else math.inf)
        worst = max(worst, r)
        if not ok:
            bad.append((name(path), x["value"], x["ci95"], y["value"], y["ci95"]))
    return {"compared": n, "identical": identical, "worst_in_half_widths": worst, "disagree": bad,
            "only_in_one": sorted(name(p) for p in set(cells_a) ^ set(cells_b))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a", help="results.json of the first run")
    ap.add_argument("b", help="results.json of the second run")
    args = ap.parse_args(argv)
    try:
        a, b = (json.loads(Path(p).read_text()) for p in (args.a, args.b))
    except (OSError, ValueError) as exc:
        print(f"compare_bench_runs: cannot read a results.json: {exc}", file=sys.stderr)
        return 2
    keys = ("controllers", "runs", "sweep", "wind_speeds_kmh", "env_kwargs")
    differ = [k for k in keys if a["bench"]["config"].get(k) != b["bench"]["config"].get(k)]
    if differ:
        print(f"compare_bench_runs: the two runs have different plans ({', '.join(differ)}): "
              f"nothing to compare", file=sys.stderr)
        return 2
    for name, r in (("a", a), ("b", b)):
        bt = r["bench"].get("blas_threads", {})
        print(f"{name}: {getattr(args, name)}: BLAS threads {bt.get('threads')}, "
              f"{r['bench']['machine']['platform']}, wall time {r['bench']['wall_time_s']['total']:.0f} s")
    results = {label: compare(a, b, keep) for label, keep in CATEGORIES.items()}
    for label, res in results.items():
        share = 100.0 * len(res["disagree"]) / max(1, res["compared"])
        print(f"{label}: {res['compared']} compared ({res['identical']} identical); largest difference "
              f"{res['worst_in_half_widths']:.3f} half-widths of the 95 % interval; "
              f"{len(res['disagree'])} ({share:.1f} %) outside the other run's interval")
        for path, va, ca, vb, cb in res["disagree"]:
            print(f"  {path}: {va:.6g} [{ca[0]:.6g}, {ca[1]:.6g}] vs {vb:.6g} [{cb[0]:.6g}, {cb[1]:.6g}]")
        if res["only_in_one"]:
            print(f"  in one run only: {', '.join(res['only_in_one'][:10])}")
    return 1 if next(iter(results.values()))["disagree"] else 0


if __name__ == "__main__":
    sys.exit(main())
