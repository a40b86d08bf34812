"""The one runner that scores every controller the same way: controller x scenario x seeds.

>>> res = run(["pi_kp1"], ["hold_side"], seeds=[0, 1], steps=300)
>>> s = res["summary"]["pi_kp1"]["hold_side"]["servo_error_mdeg"]["az"]["three_sigma"]
>>> 0.5 < s["value"] < 5.0, s["n_episodes"], len(s["ci95"])  # mdeg; Table 4: 2.1 (50 km/h side)
(True, 2, 2)

The runner's jobs are in their own modules: the controllers and scenarios are the catalog's
rows (:mod:`dss14_env.bench.catalog`); the episodes and their figures are the one episode loop
(:mod:`dss14_env.baselines.rollout`, records of :mod:`dss14_env.core.results`); the summaries
with their intervals and ratios are :mod:`dss14_env.bench.statistics`; the JSON is written
through :mod:`dss14_env.core.results`.  This module builds the environments and controllers of
each scenario, runs every controller's episodes and assembles ``{"meta", "episodes",
"summary", "yardstick"}``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dss14_env.baselines.base import Controller
from dss14_env.baselines.rollout import (
    SequentialDriver,
    batch_driver,
    episode_metrics,
    run_episode,
    run_rows,
    step_response,
)
from dss14_env.bench import catalog
from dss14_env.bench.catalog import ControllerRow, Scenario
from dss14_env.bench.statistics import (
    LEVEL,
    N_RESAMPLES,
    POOLING,
    all_reference_ratios,
    cell_rng,
    flatten,
    reference_ratios,
    summarise,
    yardstick_ratios,
    yardstick_reference,
)
from dss14_env.core.results import POINTING_AXES, jsonable
from dss14_env.core.units import AXES

#: the most rows x steps one vector environment records at once (the time histories of a batch
#: are kept until its metrics are computed); longer lists of seeds run in chunks
MAX_ROW_STEPS = 1_000_000
#: the controller every other is divided by in ``vs_reference``
REFERENCE = "pi_kp1"


#: the benchmark scenarios as the runner runs them, by name (the catalog's registered rows:
#: :data:`dss14_env.bench.catalog.SCENARIOS`)
SCENARIOS: Mapping[str, Scenario] = catalog.LiveMapping(
    lambda: {n: r.scenario() for n, r in catalog.SCENARIOS.items()})
#: controller factories by name (the catalog's rows, each called with the environment)
CONTROLLERS: Mapping[str, ControllerRow] = catalog.CONTROLLERS


def known_unbatchable(factory: Callable[[Any], Controller]) -> bool:
    """True when the factory is a catalog row that runs one episode at a time (then a scenario
    that gives such controllers no episodes need not build it).
    """
    return isinstance(factory, ControllerRow) and not factory.batchable



# ------------------------------------------------------------------------- running
def _make_env(env_kwargs: Mapping[str, Any]) -> Any:
    from dss14_env.envs.env import DSS14Env
    return DSS14Env(**dict(env_kwargs))


def _make_vector_env(env_kwargs: Mapping[str, Any], n: int) -> Any:
    from dss14_env.envs.vector import DSS14VectorEnv
    return DSS14VectorEnv(num_envs=n, **dict(env_kwargs))


def _resolve_controller(c: Any) -> tuple[str, Callable[[Any], Controller]]:
    if isinstance(c, str):
        if c not in catalog.CONTROLLERS:
            raise ValueError(f"unknown controller {c!r}; known: {sorted(catalog.CONTROLLERS)}")
        return c, catalog.CONTROLLERS[c]
    if isinstance(c, ControllerRow):
        return c.name, c
    if isinstance(c, Controller):
        return c.name, (lambda env, _c=c: _c)
    if isinstance(c, tuple) and len(c) == 2 and isinstance(c[0], str) and callable(c[1]):
        return c[0], c[1]
    raise TypeError(f"a controller must be a name of {sorted(CONTROLLERS)}, a Controller or a "
                    f"(name, factory(env)) pair, got {c!r}")


def _resolve_scenario(s: Any) -> tuple[str, Scenario]:
    if isinstance(s, str):
        if s not in catalog.SCENARIOS:
            raise ValueError(f"unknown scenario {s!r}; known: {sorted(catalog.SCENARIOS)}")
        return s, catalog.SCENARIOS[s].scenario()
    if isinstance(s, tuple) and len(s) == 2 and isinstance(s[1], Scenario):
        return s
    raise TypeError(f"a scenario must be a name of {sorted(SCENARIOS)} or a (name, Scenario) "
                    f"pair, got {s!r}")



def _chunks(seeds: Sequence[int], steps: int) -> list[list[int]]:
    size = max(1, MAX_ROW_STEPS // max(1, steps))
    return [list(seeds[i:i + size]) for i in range(0, len(seeds), size)]


@dataclass
class _ScenarioEnvs:
    """The environments of one scenario: the single one and vector ones by size."""

    kwargs: dict[str, Any]
    single: Any
    vectors: dict[int, Any]

    def vector(self, n: int) -> Any:
        if n not in self.vectors:
            self.vectors[n] = _make_vector_env(self.kwargs, n)
        return self.vectors[n]


def _sensor_envs(by_sensors: dict[tuple, _ScenarioEnvs], kw: dict[str, Any], sensors: Any) -> _ScenarioEnvs:
    """The scenario's environments with the sensors a controller row needs (the monopulse
    sensor: :attr:`dss14_env.bench.catalog.ControllerRow.sensors`); the scenario's own for a
    row that needs no more than the encoders, or for a controller that is not a row.
    """
    if sensors is None or "monopulse" not in sensors:
        return next(iter(by_sensors.values()))
    key = tuple(sensors)
    if key not in by_sensors:
        kw2 = {**kw, "sensors": list(key)}
        by_sensors[key] = _ScenarioEnvs(kw2, _make_env(kw2), {})
    return by_sensors[key]


def _controller_episodes(ctrl: Controller, envs: _ScenarioEnvs, seeds: Sequence[int], n_seq: int,
                         steps: int, warmup_s: float, record: bool, batch: bool,
                         progress: Callable[[list[dict[str, Any]]], None], move: bool = False
                         ) -> tuple[list[dict[str, Any]], bool]:
    """All episodes of one controller in one scenario, and whether it ran batched (``move``:
    score the commanded move's response).
    """
    driver = batch_driver(ctrl) if batch else None
    eps: list[dict[str, Any]] = []
    if driver is not None:
        for chunk in _chunks(seeds, steps):
            new = run_rows(driver, envs.vector(len(chunk)), chunk, steps, warmup_s, record=record and not eps,
                           move=move)
            eps += new
            progress(new)
    else:
        seq = SequentialDriver(ctrl)
        for seed in seeds[:n_seq]:
            new = run_rows(seq, envs.single, [seed], steps, warmup_s, record=record and not eps, move=move)
            eps += new
            progress(new)
    return eps, driver is not None


def _check_run(names: list[str], scens: list, seeds: list[int], sequential_seeds: int | None) -> int:
    if not names or not scens or not seeds:
        raise ValueError("run() needs at least one controller, one scenario and one seed")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be unique, got {seeds}")
    if len(set(names)) != len(names):
        raise ValueError(f"controller names must be unique, got {names}")
    n_seq = len(seeds) if sequential_seeds is None else int(sequential_seeds)
    if not 0 <= n_seq <= len(seeds):
        raise ValueError(f"sequential_seeds must be in 0..{len(seeds)}, got {sequential_seeds!r}")
    return n_seq


def _statistics_meta(n_resamples: int, bootstrap_seed: int) -> dict[str, Any]:
    return {"level": LEVEL, "n_resamples": n_resamples, "bootstrap_seed": bootstrap_seed,
            "interval": "percentile bootstrap over episodes (all metrics of a cell resampled together)",
            "ratios": "vs_reference (servo error) and vs_reference_pointing_error_mdeg (the dish's "
                      "pointing error): paired bootstrap over the common seeds; vs_yardstick: the "
                      "controller's interval over the analytic figure",
            "pooling": dict(POOLING)}


def _run_scenario(ctrls: list[tuple[str, Callable[[Any], Controller]]], sname: str, sc: Scenario,
                  seeds: list[int], n_seq: int, kw: dict[str, Any], n_steps: int, record: bool, batch: bool,
                  progress: Callable[[str, int], None] | None, reference: str | None, bootstrap_seed: int,
                  n_resamples: int) -> tuple[list[dict[str, Any]], dict[str, Any], Any, dict[str, Any]]:
    """Every controller on one scenario: its episodes, summary cells, yardstick reference and,
    per controller, whether it ran batched and its wall time (s, building it included).
    """
    envs = _ScenarioEnvs(kw, _make_env(kw), {})
    by_sensors = {tuple(kw.get("sensors", ("encoders",))): envs}
    ref = yardstick_reference(sc, envs.single)
    by_ctrl: dict[str, list[dict[str, Any]]] = {}
    cells: dict[str, Any] = {}
    flags: dict[str, Any] = {}
    for cname, factory in ctrls:
        t0 = time.perf_counter()
        if n_seq == 0 and known_unbatchable(factory):
            flags[cname] = (False, 0.0)
            continue
        def tick(eps: list[dict[str, Any]], c: str = cname) -> None:
            if progress is not None:
                progress(_progress_line(c, sname, eps), len(eps))
        cenvs = _sensor_envs(by_sensors, kw, getattr(factory, "sensors", None))
        eps, batched = _controller_episodes(factory(cenvs.single), cenvs, seeds, n_seq, n_steps,
                                            sc.warmup_s, record, batch, tick, sc.group == "move")
        flags[cname] = (batched, time.perf_counter() - t0)
        for ep in eps:
            ep.update({"controller": cname, "scenario": sname})
        if eps:
            by_ctrl[cname] = eps
            cells[cname] = summarise(eps, cell_rng(cname, sname, seed=bootstrap_seed), n_resamples)
            if ref is not None:
                cells[cname]["vs_yardstick"] = yardstick_ratios(cells[cname], ref)
                cells[cname]["vs_yardstick_pointing_error_mdeg"] = yardstick_ratios(cells[cname], ref,
                                                                                    pointing=True)
    if reference in by_ctrl:
        for cname, eps in by_ctrl.items():
            cells[cname].update(all_reference_ratios(eps, by_ctrl[reference], (cname, reference, sname),
                                                     bootstrap_seed, n_resamples))
    return [ep for eps in by_ctrl.values() for ep in eps], cells, ref, flags


def run(controllers: Iterable[Any], scenarios: Iterable[Any], seeds: Iterable[int],
        env_kwargs: Mapping[str, Any] | None = None, steps: int | None = None,
        progress: Callable[[str, int], None] | None = None, record: bool = False,
        sequential_seeds: int | None = None, batch: bool = True, reference: str | None = REFERENCE,
        bootstrap_seed: int = 0, n_resamples: int = N_RESAMPLES) -> dict[str, Any]:
    """Score controllers on scenarios over seeds.

    :param controllers: names of :data:`CONTROLLERS`, :class:`Controller` instances or
        ``(name, factory(env))`` pairs
    :param scenarios: names of :data:`SCENARIOS` or ``(name, Scenario)`` pairs
    :param seeds: episode seeds (the same for every controller)
    :param env_kwargs: environment keys applied on top of every scenario's (e.g.
        ``{"randomize_params": True}``)
    :param steps: episode length overriding the scenarios' (control periods)
    :param progress: called with a line and the number of episodes it finished, per batch or
        episode
    :param record: keep the first seed's time histories under ``episodes[i]["trace"]``
        (:func:`run_rows`; numpy arrays, left out of the JSON conversion -- drop them before
        ``json.dump``); default False
    :param sequential_seeds: controllers without the batch interface run only the first this
        many seeds (default: all)
    :param batch: drive batchable controllers through the vector environment (default); False
        runs every controller one episode at a time
    :param reference: the controller of ``vs_reference`` (default ``pi_kp1``; skipped when it
        does not run)
    :param bootstrap_seed: seed of the bootstrap generators
    :param n_resamples: bootstrap resamples
    :return: ``{"meta", "episodes", "summary", "yardstick"}``, JSON-serialisable (without
        traces): ``summary[controller][scenario]`` (:func:`summarise`, plus ``vs_reference`` and
        ``vs_yardstick`` where defined)
    """
    ctrls = [_resolve_controller(c) for c in controllers]
    scens = [_resolve_scenario(s) for s in scenarios]
    seeds = [int(s) for s in seeds]
    names = [n for n, _ in ctrls]
    n_seq = _check_run(names, scens, seeds, sequential_seeds)
    env_kwargs = dict(env_kwargs or {})
    episodes: list[dict[str, Any]] = []
    summary: dict[str, dict[str, Any]] = {n: {} for n in names}
    yard: dict[str, Any] = {}
    batched: dict[str, bool] = {}
    wall: dict[str, dict[str, float]] = {n: {} for n in names}
    t_start = time.perf_counter()
    for sname, sc in scens:
        eps, cells, ref, flags = _run_scenario(ctrls, sname, sc, seeds, n_seq, {**sc.env, **env_kwargs},
                                               int(steps or sc.steps), record, batch, progress, reference,
                                               bootstrap_seed, n_resamples)
        episodes += eps
        for cname, (b, t) in flags.items():
            batched[cname] = b
            wall[cname][sname] = t
        for cname, cell in cells.items():
            summary[cname][sname] = cell
        if ref is not None:
            yard[sname] = ref
    meta = {"controllers": names, "scenarios": [n for n, _ in scens], "seeds": seeds,
            "sequential_seeds": seeds[:n_seq], "batched": batched,
            "reference": reference if reference in names else None,
            "env_kwargs": env_kwargs, "steps": {n: int(steps or sc.steps) for n, sc in scens},
            "warmup_s": {n: sc.warmup_s for n, sc in scens}, "groups": {n: sc.group for n, sc in scens},
            "statistics": _statistics_meta(n_resamples, bootstrap_seed),
            "wall_time_s": time.perf_counter() - t_start, "controller_wall_time_s": wall}
    traces = [ep.pop("trace", None) for ep in episodes]
    out = jsonable({"meta": meta, "episodes": episodes, "summary": summary, "yardstick": yard})
    for ep, tr in zip(out["episodes"], traces, strict=True):
        if tr is not None:
            ep["trace"] = tr
    return out


def _progress_line(cname: str, sname: str, eps: Sequence[Mapping[str, Any]]) -> str:
    se = [ep["servo_error_mdeg"] for ep in eps]
    az = float(np.mean([s["az"]["three_sigma"] for s in se]))
    el = float(np.mean([s["el"]["three_sigma"] for s in se]))
    seeds = f"seed {eps[0]['seed']}" if len(eps) == 1 else f"{len(eps)} seeds"
    return f"{cname:>10s} {sname:>10s} {seeds}: 3-sigma az {az:.3f} el {el:.3f} mdeg"


def ratio(summary: Mapping[str, Any], num: str, den: str, scenario: str, axis: str,
          stat: str = "three_sigma") -> float:
    """``summary[num][scenario]`` over ``summary[den][scenario]`` for the pooled value of a
    servo-error statistic on one axis (e.g. LQG over PI; ``vs_reference`` has it with its
    interval).
    """
    a = summary[num][scenario]["servo_error_mdeg"][axis][stat]["value"]
    b = summary[den][scenario]["servo_error_mdeg"][axis][stat]["value"]
    return float(a / b)




__all__ = ["AXES", "CONTROLLERS", "LEVEL", "MAX_ROW_STEPS", "N_RESAMPLES", "POINTING_AXES", "POOLING",
           "REFERENCE", "SCENARIOS", "Scenario", "batch_driver", "cell_rng", "episode_metrics",
           "flatten", "jsonable", "known_unbatchable", "ratio", "reference_ratios", "run",
           "run_episode", "run_rows", "step_response", "summarise", "yardstick_ratios",
           "yardstick_reference"]
