"""Running a :class:`~dss14_env.bench.plan.BenchPlan` through the one runner.

:func:`run_plan` calls :func:`dss14_env.bench.runner.run` once per scenario (each with its own
episode length and seeds) and once per point of the error-vs-wind sweep, with a progress bar,
and merges the runner's outputs.  A sweep point identical to a main scenario (same environment
keys, episode length and warm-up: the 50 km/h points) is taken from it, not rerun.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from dss14_env.bench import catalog, runner
from dss14_env.bench.plan import SWEEP_DIRECTIONS, BenchPlan, ScenarioRun, sweep_name, sweep_scenario
from dss14_env.bench.runner import Scenario
from dss14_env.core.progress import Progress
from dss14_env.model.variants import DRIVE_VARIANTS

#: scenarios whose first seed's time histories the figures draw (the catalog's traced rows)


def controller_entries(plan: BenchPlan) -> list[Any]:
    """The runner's controller arguments: the plan's catalog rows."""
    return list(plan.rows)


def sweep_points(plan: BenchPlan) -> list[tuple[str, str, float, Scenario, str | None]]:
    """(name, direction, speed, scenario, the main scenario it equals or None) per sweep point
    (equal: same environment keys, episode length and warm-up).
    """
    pts = []
    for d in plan.sweep_directions:
        for v in plan.wind_speeds_kmh:
            sc = sweep_scenario(d, v, plan.sweep.steps)
            same = next((s for s in plan.scenarios if dict(plan.scenario(s).env) == dict(sc.env)
                         and plan.runs[s].steps == sc.steps and plan.scenario(s).warmup_s == sc.warmup_s),
                        None)
            pts.append((sweep_name(d, v), d, v, sc, same))
    return pts


def variant_name(scenario: str, variant: str) -> str:
    """Name of a hold scenario on a drive variant, e.g. ``hold_front@stiff``."""
    return f"{scenario}@{variant}"


def variant_points(plan: BenchPlan) -> list[tuple[str, str, str, Scenario]]:
    """(name, scenario, variant, runner scenario) per hold scenario on a drive variant: the
    scenario's environment on the variant's model file, the variant run's episode length.
    """
    pts = []
    for v in plan.variants:
        for s in plan.variant_scenarios:
            base = plan.scenario(s)
            sc = Scenario({**base.env, "model_config": DRIVE_VARIANTS[v].config}, plan.variant_run.steps,
                          base.warmup_s, f"{base.description} on the {v} drive variant")
            pts.append((variant_name(s, v), s, v, sc))
    return pts


def _merge(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """One runner result from several (each one scenario or sweep point)."""
    if not parts:
        return {"meta": {}, "episodes": [], "summary": {}, "yardstick": {}}
    meta: dict[str, Any] = {k: v for k, v in parts[0]["meta"].items()}
    for key in ("scenarios",):
        meta[key] = [s for p in parts for s in p["meta"][key]]
    for key in ("steps", "warmup_s", "groups"):
        meta[key] = {k: v for p in parts for k, v in p["meta"][key].items()}
    meta["seeds"] = {s: p["meta"]["seeds"] for p in parts for s in p["meta"]["scenarios"]}
    meta["sequential_seeds"] = {s: p["meta"]["sequential_seeds"]
                                for p in parts for s in p["meta"]["scenarios"]}
    meta["batched"] = {c: any(p["meta"]["batched"].get(c, False) for p in parts) for c in meta["controllers"]}
    meta["wall_time_s"] = sum(p["meta"]["wall_time_s"] for p in parts)
    meta["controller_wall_time_s"] = {
        c: {s: t for p in parts for s, t in p["meta"]["controller_wall_time_s"][c].items()}
        for c in meta["controllers"]}
    summary: dict[str, dict[str, Any]] = {c: {} for c in meta["controllers"]}
    for p in parts:
        for c, cells in p["summary"].items():
            summary[c].update(cells)
    return {"meta": meta, "episodes": [ep for p in parts for ep in p["episodes"]], "summary": summary,
            "yardstick": {k: v for p in parts for k, v in p["yardstick"].items()}}


def _run_one(plan: BenchPlan, ctrls: list[Any], name: str, sc: Scenario, r: ScenarioRun,
             cb: Callable[[str, int], None] | None, record: bool) -> dict[str, Any]:
    return runner.run(ctrls, [(name, sc)], r.seeds, plan.env_kwargs, progress=cb, record=record,
                      sequential_seeds=r.sequential, bootstrap_seed=plan.bootstrap_seed)


def _expected_episodes(plan: BenchPlan, runs: list[ScenarioRun]) -> int:
    """Episodes of the run (the progress bar's total; corrected as the run goes): every seed
    for a batchable row, the first ``sequential`` for the others.
    """
    return sum(len(r.seeds) if row.batchable else r.sequential for r in runs for row in plan.rows)


def run_plan(plan: BenchPlan, progress: bool = True) -> dict[str, Any]:
    """Run the plan: the main scenarios (with the first seed's time histories of the hold and
    step scenarios) and the wind sweep.

    :param plan: the plan (:func:`dss14_env.bench.plan.build_plan`)
    :param progress: show the episodes done on stderr (:class:`~dss14_env.core.progress.Progress`:
        a bar on a terminal, lines otherwise)
    :return: ``{"main": runner result (episodes with ``trace``), "sweep": runner result of the
        sweep points that ran (or None), "variants": runner result of the hold scenarios on the
        drive variants (or None), "sweep_points": [(name, direction, speed, same_as)],
        "variant_points": [(name, scenario, variant)], "wall_time_s": {"main", "sweep",
        "variants"}}``
    """
    ctrls = controller_entries(plan)
    points = sweep_points(plan)
    to_run = [(n, sc) for n, _, _, sc, same in points if same is None]
    variants = variant_points(plan)
    v_ctrls = [r for r in ctrls if r.name in plan.variant_controllers]
    total = (_expected_episodes(plan, list(plan.runs.values()) + [plan.sweep] * len(to_run))
             + len(variants) * len(v_ctrls) * len(plan.variant_run.seeds))
    t0 = time.perf_counter()
    with Progress(total, "bench", unit="episodes", enabled=progress) as bar:
        def tick(line: str, n: int) -> None:
            head, _, tail = line.partition(":")
            bar.set_description(" ".join(head.split()))
            bar.set_note(tail.strip())
            bar.update(n)

        main = _merge([_run_one(plan, ctrls, s, plan.scenario(s), plan.runs[s], tick,
                                catalog.SCENARIOS[s].traced) for s in plan.scenarios])
        t1 = time.perf_counter()
        sweep = _merge([_run_one(plan, ctrls, n, sc, plan.sweep, tick, False) for n, sc in to_run]) \
            if to_run else None
        t2 = time.perf_counter()
        var = _merge([_run_one(plan, v_ctrls, n, sc, plan.variant_run, tick, False)
                      for n, _, _, sc in variants]) if variants else None
        bar.set_total(bar.n)
    t3 = time.perf_counter()
    return {"main": main, "sweep": sweep, "variants": var,
            "sweep_points": [(n, d, v, same) for n, d, v, _, same in points],
            "variant_points": [(n, s, v) for n, s, v, _ in variants],
            "wall_time_s": {"main": t1 - t0, "sweep": t2 - t1, "variants": t3 - t2}}


__all__ = ["controller_entries", "run_plan", "sweep_points", "SWEEP_DIRECTIONS", "variant_name",
           "variant_points"]
