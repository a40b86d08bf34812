"""Running a :class:`~dss14_env.bench.plan.BenchPlan` through the one runner.

:func:`run_plan` calls :func:`dss14_env.bench.runner.run` once per scenario (each with its own
episode length and seeds) and once per point of the error-vs-wind sweep, with a progress bar,
and merges the runner's outputs.  A sweep point identical to a main scenario (same environment
keys, episode length and warm-up: the 50 km/h points) is taken from it, not rerun.
"""

from __future__ import annotations

import multiprocessing
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from dss14_env.bench import catalog, runner
from dss14_env.bench.plan import SWEEP_DIRECTIONS, BenchPlan, ScenarioRun, sweep_name, sweep_scenario
from dss14_env.bench.runner import Scenario
from dss14_env.bench.threads import blas_threads
from dss14_env.core.progress import Progress
from dss14_env.envs.plant import resolve_factory
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


#: a one-at-a-time episode's cost in batched episodes of the same length (the MPC's QP per
#: period against a row of the vector environment), for ordering the units only
SEQUENTIAL_WEIGHT = 30.0


@dataclass(frozen=True)
class _Unit:
    """One independent piece of the run: one runner call (part ``main``, ``sweep`` or
    ``variants``).
    """

    part: str
    name: str
    scenario: Scenario
    run: ScenarioRun
    ctrls: tuple[Any, ...]
    record: bool


def _run_one(plan: BenchPlan, ctrls: list[Any], name: str, sc: Scenario, r: ScenarioRun,
             cb: Callable[[str, int], None] | None, record: bool) -> dict[str, Any]:
    return runner.run(ctrls, [(name, sc)], r.seeds, plan.env_kwargs, progress=cb, record=record,
                      sequential_seeds=r.sequential, bootstrap_seed=plan.bootstrap_seed)


def _expected_episodes(plan: BenchPlan, runs: list[ScenarioRun]) -> int:
    """Episodes of the run (the progress bar's total; corrected as the run goes): every seed
    for a batchable row, the first ``sequential`` for the others.
    """
    return sum(len(r.seeds) if row.batchable else r.sequential for r in runs for row in plan.rows)


def _units(plan: BenchPlan, ctrls: list[Any], to_run: list[tuple[str, Scenario]],
           variants: list[tuple[str, str, str, Scenario]], v_ctrls: list[Any]) -> list[_Unit]:
    """The run's independent units, in the serial run's order: a main scenario (with its traces),
    a sweep point or a hold scenario on a drive variant, each with every controller it runs.
    """
    units = [_Unit("main", s, plan.scenario(s), plan.runs[s], tuple(ctrls), catalog.SCENARIOS[s].traced)
             for s in plan.scenarios]
    units += [_Unit("sweep", n, sc, plan.sweep, tuple(ctrls), False) for n, sc in to_run]
    units += [_Unit("variants", n, sc, plan.variant_run, tuple(v_ctrls), False) for n, _, _, sc in variants]
    return units


def _unit_cost(u: _Unit) -> float:
    """A unit's rough cost, to start the largest first: control periods simulated, an episode of
    a one-at-a-time row (the MPC) counted as :data:`SEQUENTIAL_WEIGHT` batched ones.
    """
    return float(sum(u.run.steps * (len(u.run.seeds) if row.batchable
                                    else SEQUENTIAL_WEIGHT * u.run.sequential) for row in u.ctrls))


#: the plan of this worker process (set by :func:`_init_worker`)
_WORKER_PLAN: list[BenchPlan] = []


def _init_worker(plan: BenchPlan) -> None:
    """A worker of the pool: Ctrl-C is the parent's to handle, SIGTERM (how the pool ends its
    workers) ends the worker quietly, whatever handler the forked parent had; the plan's BLAS
    threads.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _WORKER_PLAN.append(plan)
    blas_threads(plan.threads).__enter__()  # for the worker's life (it ends with the pool)


def _run_unit(item: tuple[int, _Unit]) -> tuple[int, dict[str, Any], float]:
    """One unit in a worker: (its index, the runner's result, its wall time)."""
    i, u = item
    t0 = time.perf_counter()
    res = _run_one(_WORKER_PLAN[0], list(u.ctrls), u.name, u.scenario, u.run, None, u.record)
    return i, res, time.perf_counter() - t0


#: control periods of the warm-up episode (:func:`warm_up`)
WARM_UP_STEPS = 2
#: bootstrap resamples of the warm-up's summaries (discarded)
WARM_UP_RESAMPLES = 10


def warm_up(plan: BenchPlan, units: list[_Unit]) -> None:
    """Do once, before the pool forks (its workers start as copies of this process), what each
    worker would otherwise do again: build every controller of the units (the policies' files
    read and checked, the LQG designs computed) and run it for :data:`WARM_UP_STEPS` periods
    of the first seed of the first unit's scenario (the environments' compiled loops, numba's,
    compiled for the single and the vector environment), and build the model of every
    scenario's model file (a drive variant's calibration).  Nothing of it is scored.
    """
    if not units:
        return
    rows = list({id(r): r for u in units for r in u.ctrls}.values())
    first = units[0]
    runner.run(rows, [("warm-up", catalog.replace_steps(first.scenario, WARM_UP_STEPS))],
               first.run.seeds[:1], plan.env_kwargs, sequential_seeds=1, reference=None,
               bootstrap_seed=plan.bootstrap_seed, n_resamples=WARM_UP_RESAMPLES)
    models = {u.scenario.env.get("model_config") for u in units}
    for model in sorted(models - {None, first.scenario.env.get("model_config")}, key=str):
        resolve_factory(model)


def _run_pool(plan: BenchPlan, units: list[_Unit], jobs: int,
              done: Callable[[_Unit, dict[str, Any]], None]) -> tuple[list[dict[str, Any]], dict[str, float]]:
    """The units in ``jobs`` worker processes, largest first; their results in the units' order
    and the summed wall time of each part's units (s).
    """
    results: list[dict[str, Any] | None] = [None] * len(units)
    wall = {"main": 0.0, "sweep": 0.0, "variants": 0.0}
    order = sorted(range(len(units)), key=lambda i: -_unit_cost(units[i]))
    # fork: the workers start with the parent's imports and plan (spawn where there is none)
    fork = "fork" in multiprocessing.get_all_start_methods()
    ctx = multiprocessing.get_context("fork" if fork else "spawn")
    if fork:
        warm_up(plan, units)
    with ctx.Pool(min(jobs, len(units)), _init_worker, (plan,)) as pool:
        for i, res, t in pool.imap_unordered(_run_unit, [(i, units[i]) for i in order], chunksize=1):
            results[i] = res
            wall[units[i].part] += t
            done(units[i], res)
    return [r for r in results if r is not None], wall


def run_plan(plan: BenchPlan, progress: bool = True) -> dict[str, Any]:
    """Run the plan: the main scenarios (with the first seed's time histories of the hold and
    step scenarios) and the wind sweep.

    With ``plan.jobs`` above 1 the units (:func:`_units`: a scenario, a sweep point, a variant
    point) run in that many worker processes, largest first, and the progress shows each unit
    as it finishes; every episode is seeded as in the serial run and the results are merged in
    the serial run's order, so both give the same numbers.

    :param plan: the plan (:func:`dss14_env.bench.plan.build_plan`)
    :param progress: show the episodes done on stderr (:class:`~dss14_env.core.progress.Progress`:
        a bar on a terminal, lines otherwise)
    :return: ``{"main": runner result (episodes with ``trace``), "sweep": runner result of the
        sweep points that ran (or None), "variants": runner result of the hold scenarios on the
        drive variants (or None), "sweep_points": [(name, direction, speed, same_as)],
        "variant_points": [(name, scenario, variant)], "wall_time_s": {"main", "sweep",
        "variants"}}`` (in processes: each part's units' summed wall time, and ``"pool"``, the
        pool's own)
    """
    ctrls = controller_entries(plan)
    points = sweep_points(plan)
    to_run = [(n, sc) for n, _, _, sc, same in points if same is None]
    variants = variant_points(plan)
    v_ctrls = [r for r in ctrls if r.name in plan.variant_controllers]
    total = (_expected_episodes(plan, list(plan.runs.values()) + [plan.sweep] * len(to_run))
             + len(variants) * len(v_ctrls) * len(plan.variant_run.seeds))
    units = _units(plan, ctrls, to_run, variants, v_ctrls)
    t0 = time.perf_counter()
    with Progress(total, "bench", unit="episodes", enabled=progress) as bar:
        def tick(line: str, n: int) -> None:
            head, _, tail = line.partition(":")
            bar.set_description(" ".join(head.split()))
            bar.set_note(tail.strip())
            bar.update(n)

        if plan.jobs > 1 and len(units) > 1:
            def done(u: _Unit, res: dict[str, Any]) -> None:
                tick(f"{u.name}: {len(res['episodes'])} episodes", len(res["episodes"]))

            parts, wall = _run_pool(plan, units, plan.jobs, done)
            wall["pool"] = time.perf_counter() - t0
        else:
            parts, wall, t = [], {}, t0
            for u in units:
                parts.append(_run_one(plan, list(u.ctrls), u.name, u.scenario, u.run, tick, u.record))
                now = time.perf_counter()
                wall[u.part] = wall.get(u.part, 0.0) + now - t
                t = now
        bar.set_total(bar.n)
    by_part = {k: [p for u, p in zip(units, parts, strict=True) if u.part == k]
               for k in ("main", "sweep", "variants")}
    return {"main": _merge(by_part["main"]), "sweep": _merge(by_part["sweep"]) if to_run else None,
            "variants": _merge(by_part["variants"]) if variants else None,
            "sweep_points": [(n, d, v, same) for n, d, v, _, same in points],
            "variant_points": [(n, s, v) for n, s, v, _ in variants],
            "wall_time_s": {"main": wall.get("main", 0.0), "sweep": wall.get("sweep", 0.0),
                            "variants": wall.get("variants", 0.0),
                            **({"pool": wall["pool"]} if "pool" in wall else {})}}


__all__ = ["controller_entries", "run_plan", "sweep_points", "SWEEP_DIRECTIONS", "variant_name",
           "variant_points", "warm_up", "WARM_UP_RESAMPLES", "WARM_UP_STEPS"]
