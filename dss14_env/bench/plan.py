"""The bench's options turned into a validated :class:`BenchPlan` (:func:`build_plan`).

Every option is checked here, before any work, and a bad one raises :class:`BenchOptionError`
whose message starts with the option's name.  The plan gives each scenario the episode length
and the number of episodes its statistics need (:data:`DEFAULT_BUDGETS`): controllers that act
on batches (PI, LQG, PPO) run many episodes at once through the vector environment, the MPC
(one episode at a time) runs the first few of the same seeds.

>>> plan = build_plan(controllers=["pi_kp1"], scenarios=["step"], quick=True)
>>> plan.runs["step"].steps, len(plan.runs["step"].seeds), plan.runs["step"].sequential
(750, 4, 1)
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.bench import catalog
from dss14_env.bench.catalog import Budget, ControllerRow, LiveMapping, Scenario
from dss14_env.core.counts import MAX_EPISODE_STEPS, MAX_EPISODES, MAX_THREADS, check_count
from dss14_env.core.seeds import parse_seed_list
from dss14_env.core.text import counted
from dss14_env.model.variants import DRIVE_VARIANTS

#: per scenario, the default run's budget and the ``--quick`` one (the catalog's rows)
DEFAULT_BUDGETS: Mapping[str, Budget] = LiveMapping(
    lambda: {n: r.default for n, r in catalog.SCENARIOS.items()})
QUICK_BUDGETS: Mapping[str, Budget] = LiveMapping(lambda: {n: r.quick for n, r in catalog.SCENARIOS.items()})
#: a point of the error-vs-wind sweep (the MPC is left out: the 50 km/h points are the hold
#: scenarios, where it runs)
DEFAULT_SWEEP = Budget(60.0, 32, 0)
#: ``--quick``: the CI smoke test
QUICK_SWEEP = Budget(15.0, 8, 0)
#: controllers of a run without ``--controllers``: the shipped bench rows (with registered
#: rows: :func:`dss14_env.bench.catalog.controller_names`)
DEFAULT_CONTROLLERS: tuple[str, ...] = catalog.controller_names("bench")
#: scenarios of a run without ``--scenarios``: the shipped bench rows (with registered rows:
#: :func:`dss14_env.bench.catalog.scenario_names`)
DEFAULT_SCENARIOS: tuple[str, ...] = catalog.scenario_names("bench")
#: wind speeds (km/h) of the ``--quick`` error-vs-wind sweep without ``--wind-speeds`` (the
#: default sweep is the environment's grid, :func:`default_wind_speeds`)
QUICK_WIND_SPEEDS_KMH: tuple[float, ...] = (30.0, 50.0, 70.0)
#: the drive variants a run scores the pointing error on without ``--variants``
#: (:data:`dss14_env.model.variants.DRIVE_VARIANTS`), in the selected hold scenarios
DEFAULT_VARIANTS: tuple[str, ...] = tuple(DRIVE_VARIANTS)
#: the controllers that run on the drive variants (when selected): the report's PI and the
#: model-based controllers, all designed on the nominal model (the one-at-a-time MPC is left
#: out for time)
VARIANT_CONTROLLERS: tuple[str, ...] = ("pi_kp1", "lqg", "lqg_pointing")
#: a hold scenario on a drive variant: episodes like a sweep point's
DEFAULT_VARIANT_RUN = Budget(60.0, 32, 0)
QUICK_VARIANT_RUN = Budget(15.0, 8, 0)
#: warm-up of a sweep point, s (the hold scenarios')
SWEEP_WARMUP_S = 5.0
#: the sweep's directions, the hold scenario each extends and the axis the wind acts on most
SWEEP_DIRECTIONS: Mapping[str, tuple[str, str]] = LiveMapping(
    lambda: {r.sweep: (r.name, r.loaded_axes[0]) for r in catalog.SCENARIOS.values() if r.sweep is not None})
#: the axis the wind loads per scenario (bold in the tables; the precision target's axis)
LOADED_AXES: Mapping[str, tuple[str, ...]] = LiveMapping(
    lambda: {r.name: r.loaded_axes for r in catalog.SCENARIOS.values() if r.loaded_axes})
#: default BLAS threads while running
DEFAULT_THREADS = 1
#: most worker processes of a run without ``--jobs``
MAX_DEFAULT_JOBS = 8


def default_jobs() -> int:
    """Worker processes without ``--jobs``: the CPUs this process may use, at most
    :data:`MAX_DEFAULT_JOBS`.
    """
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cpus, MAX_DEFAULT_JOBS))


class BenchOptionError(ValueError):
    """A bad bench option; the message starts with the option's name."""


@dataclass(frozen=True)
class ScenarioRun:
    """What one scenario (or sweep point) runs.

    :param steps: control periods per episode
    :param seeds: seeds of the batched controllers
    :param sequential: the first this many seeds are the episodes of the other controllers
    """

    steps: int
    seeds: tuple[int, ...]
    sequential: int

    @property
    def sequential_seeds(self) -> tuple[int, ...]:
        return self.seeds[:self.sequential]


@dataclass
class BenchPlan:
    """Everything a bench run needs, resolved and validated (:func:`build_plan`).

    :param controllers: controller names (the names of ``rows``)
    :param scenarios: scenario names of :data:`dss14_env.bench.catalog.SCENARIOS`
    :param runs: per scenario, its episode length and seeds (:class:`ScenarioRun`)
    :param wind_speeds_kmh: speeds of the error-vs-wind sweep
    :param sweep_directions: ``"front"`` and/or ``"side"`` (those of the selected hold
        scenarios); empty: no sweep
    :param sweep: what a sweep point runs
    :param variants: drive variants (:data:`dss14_env.model.variants.DRIVE_VARIANTS`) whose
        hold scenarios run too; empty: none
    :param variant_run: what a hold scenario on a variant runs
    :param env_kwargs: environment keys on top of every scenario's
    :param rows: the catalog rows that run (:func:`controller_rows`; a ``--ppo-model`` policy
        is a row of its own name)
    :param dt: the environment's control period, s (seconds to steps)
    :param ppo_model: ``--ppo-model`` as given (None: the shipped policy of its row)
    :param out: output folder
    :param overwrite: replace the bench's files in an output folder that has them
    :param figures: draw the PNG figures
    :param threads: BLAS threads while running (None: leave them)
    :param jobs: worker processes running the scenarios, sweep points and variant points side
        by side (1: all in this process, one after another)
    :param quick: the plan came from ``--quick`` (for the record)
    :param bootstrap_seed: seed of the confidence intervals' resampling
    :param notes: warnings found while building the plan (printed, stored in results.json)
    :param command: the command line, for the record
    """

    controllers: list[str]
    scenarios: list[str]
    runs: dict[str, ScenarioRun]
    wind_speeds_kmh: list[float]
    sweep_directions: list[str]
    sweep: ScenarioRun
    variants: list[str] = field(default_factory=list)
    variant_run: ScenarioRun = ScenarioRun(0, (), 0)
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    rows: tuple[ControllerRow, ...] = ()
    dt: float = 0.02
    ppo_model: str | None = None
    out: Path = Path("bench_out")
    overwrite: bool = False
    figures: bool = True
    threads: int | None = DEFAULT_THREADS
    jobs: int = 1
    quick: bool = False
    bootstrap_seed: int = 0
    notes: list[str] = field(default_factory=list)
    command: str | None = None

    def scenario(self, name: str) -> Scenario:
        """The runner scenario ``name`` with the plan's episode length."""
        return dataclasses.replace(catalog.SCENARIOS[name].scenario(), steps=self.runs[name].steps)

    def as_dict(self) -> dict[str, Any]:
        """The plan, JSON-ready (the ``bench.config`` entry of results.json)."""
        d = dataclasses.asdict(self)
        d["out"] = str(self.out)
        d["runs"] = {s: self._run_dict(r, self.scenario(s).warmup_s) for s, r in self.runs.items()}
        d["sweep"] = self._run_dict(self.sweep, SWEEP_WARMUP_S)
        d["variant_run"] = self._run_dict(self.variant_run, SWEEP_WARMUP_S)
        d["rows"] = [r.name for r in self.rows]
        d["policies"] = {r.name: r.policy_label() for r in self.rows if r.policy is not None}
        return d

    def _run_dict(self, r: ScenarioRun, warmup_s: float) -> dict[str, Any]:
        return {"steps": r.steps, "seconds": r.steps * self.dt, "seeds": list(r.seeds),
                "sequential_seeds": list(r.sequential_seeds), "warmup_s": warmup_s}

    def describe(self) -> str:
        """One line: what the plan runs."""
        parts = [f"{s} {r.steps * self.dt:g} s x {len(r.seeds)} (one-at-a-time: {r.sequential})"
                 for s, r in self.runs.items()]
        line = (f"bench: {counted(len(self.controllers), 'controller')} ({', '.join(self.controllers)}); "
                f"episodes per scenario: {'; '.join(parts)}")
        if self.sweep_directions:
            line += (f"; wind sweep {'/'.join(self.sweep_directions)} at "
                     f"{', '.join(f'{v:g}' for v in self.wind_speeds_kmh)} km/h "
                     f"({self.sweep.steps * self.dt:g} s x {len(self.sweep.seeds)}, one-at-a-time: "
                     f"{self.sweep.sequential})")
        if self.variants:
            line += (f"; drive variants {', '.join(self.variants)} ({', '.join(self.variant_controllers)}; "
                     f"{self.variant_run.steps * self.dt:g} s x {len(self.variant_run.seeds)})")
        if self.env_kwargs:
            line += f"; env {self.env_kwargs}"
        return line

    @property
    def variant_scenarios(self) -> list[str]:
        """The hold scenarios the drive variants run (those of the plan's scenarios)."""
        return [s for s, _ in SWEEP_DIRECTIONS.values() if s in self.scenarios] if self.variants else []

    @property
    def variant_controllers(self) -> list[str]:
        """The plan's controllers that run on the drive variants (:data:`VARIANT_CONTROLLERS`)."""
        return [c for c in self.controllers if c in VARIANT_CONTROLLERS]


# ------------------------------------------------------------------------------ options
def check_names(names: Sequence[Any], known: Sequence[str], option: str, what: str,
                error: type[ValueError] = BenchOptionError) -> list[Any]:
    """A list of names checked: not empty, every one known, none repeated.

    :param option: the option's name, first in every message; ``what`` the kind of name
    :param error: the exception class raised (a :class:`ValueError`)
    :raises error: one line naming the option and the first problem (with a near name)
    """
    names = list(names)
    if not names:
        raise error(f"{option}: give at least one {what}")
    for n in names:
        if n not in known:
            near = difflib.get_close_matches(str(n), known, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise error(f"{option}: unknown {what} {n!r}{hint}; known: {', '.join(known)}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise error(f"{option}: {what} named twice: {', '.join(dup)}")
    return names


def _names(values: Sequence[str] | None, known: Sequence[str], option: str, what: str
           ) -> list[str] | None:
    """Validate a list of names: known, unique, not empty (:func:`check_names`)."""
    if values is None:
        return None
    return check_names([str(v) for v in values], known, option, what)


def _check_seeds(seeds: Sequence[int]) -> list[int]:
    """Seeds taken literally: non-negative, not repeated, at least one."""
    if len(seeds) == 0:
        raise BenchOptionError("--seeds: give a count (e.g. 3) or the seeds (e.g. 0 1 2)")
    for x in seeds:
        if x < 0:
            raise BenchOptionError(f"--seeds: seeds are non-negative integers, got {x}")
    dup = sorted({s for s in seeds if list(seeds).count(s) > 1})
    if dup:
        raise BenchOptionError(f"--seeds: seed repeated: {', '.join(map(str, dup))}")
    return [int(x) for x in seeds]


def parse_seeds(values: Sequence[str | int] | None) -> list[int] | None:
    """``--seeds`` as on the command line, the grammar of every command
    (:func:`dss14_env.core.seeds.parse_seed_list`): seeds and ranges, ``0 3 7`` or ``0-4``; a
    single value is that seed (a count of episodes is ``--episodes N``).

    :param values: the option's values (strings from the command line, or ints)
    :return: the seeds, or None when the option was not given
    :raises BenchOptionError: not seeds or ranges, an empty range, a repeated seed, none
    """
    if values is None:
        return None
    return parse_seed_list(values, "--seeds", BenchOptionError)


def parse_episodes(value: int | str | None) -> list[int] | None:
    """``--episodes N``: the first N seeds, 0 .. N-1 (None: not given).

    :raises BenchOptionError: not an integer >= 1
    """
    if value is None:
        return None
    try:
        n = int(str(value), 10)
    except ValueError:
        raise BenchOptionError(f"--episodes: {value!r} is not an integer") from None
    return list(range(check_count(n, "--episodes", 1, MAX_EPISODES, BenchOptionError)))


def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _seed_option(seeds: int | Sequence[str | int] | None) -> list[int] | None:
    """build_plan's ``seeds``: an int is a count (:func:`parse_episodes`), a sequence of ints
    the seeds themselves, strings (command-line values) go through :func:`parse_seeds`.
    """
    if seeds is None:
        return None
    if _is_int(seeds):
        return parse_episodes(int(seeds))
    seeds = list(seeds)
    if seeds and all(_is_int(s) for s in seeds):
        return _check_seeds([int(s) for s in seeds])
    return parse_seeds(seeds)


#: light winds the sweep adds below the environment's grid: the Ka-band wind envelope
#: (:mod:`dss14_env.bench.envelope`) needs a speed each controller still meets it at
LIGHT_WIND_SPEEDS_KMH: tuple[float, ...] = (10.0, 20.0)


def default_wind_speeds() -> tuple[float, ...]:
    """The sweep's speeds without ``--wind-speeds``, km/h: :data:`LIGHT_WIND_SPEEDS_KMH` and the
    environment's ``wind_speed_grid_kmh`` (``configs/env.yaml``, the grid ``DSS14-v0`` draws
    from).
    """
    from dss14_env.envs.config import load_env_config  # (the environment, loaded when used)

    grid = tuple(load_env_config().wind_speed_grid_kmh)
    return tuple(sorted(set(LIGHT_WIND_SPEEDS_KMH + grid)))


def parse_wind_speeds(values: Sequence[str | float] | None, error: type[ValueError] = BenchOptionError,
                      hint: str = " (or --no-sweep)") -> list[float] | None:
    """``--wind-speeds`` of ``dss14 bench`` and ``dss14 campaign``: mean wind speeds, km/h, each
    in (0, 90] (the environment's own bound,
    :data:`dss14_env.envs.config.WIND_SPEED_MAX_KMH`), sorted.

    :param values: the option's values (None: not given)
    :param error: the command's option error
    :param hint: added to the message for no speed at all
    :raises error: none, not numbers (a bool is not a number), out of range or repeated
    """
    from dss14_env.envs.config import WIND_SPEED_MAX_KMH  # (the environment, loaded when used)

    if values is None:
        return None
    if len(values) == 0:
        raise error(f"--wind-speeds: give at least one speed in km/h{hint}")
    speeds = []
    for v in values:
        try:
            if isinstance(v, bool):
                raise TypeError
            x = float(v)
        except (TypeError, ValueError):
            raise error(f"--wind-speeds: {v!r} is not a number (km/h)") from None
        if not (math.isfinite(x) and 0.0 < x <= WIND_SPEED_MAX_KMH):
            raise error(f"--wind-speeds: {v} km/h is outside (0, {WIND_SPEED_MAX_KMH:g}] "
                        f"km/h, the environment's wind_speed_kmh range (WIND_SPEED_MAX_KMH)")
        speeds.append(x)
    if len(set(speeds)) != len(speeds):
        raise error(f"--wind-speeds: a speed is repeated: {list(values)}")
    return sorted(speeds)


def _count(value: Any, option: str, low: int, high: int) -> int | None:
    return None if value is None else check_count(value, option, low, high, BenchOptionError)


def _budget(scenario: str, quick: bool) -> Budget:
    row = catalog.SCENARIOS[scenario]
    return row.quick if quick else row.default


def control_period(env_kwargs: Mapping[str, Any] | None = None) -> float:
    """The environment's control period ``dt``, s (``configs/env.yaml`` with ``env_kwargs``)."""
    from dss14_env.envs.config import load_env_config
    return float(load_env_config(**dict(env_kwargs or {})).dt)


def controller_rows(names: Sequence[str] | None, ppo_model: str | Path | None = None
                    ) -> tuple[list[ControllerRow], list[str]]:
    """The catalog rows of ``--controllers`` (None: the bench's default rows), with
    ``--ppo-model`` replacing the :data:`~dss14_env.bench.catalog.POLICY_OPTION_ROW` row by the
    given policy under its own name, and the notes of default policies that cannot be loaded
    (those are left out; a policy asked for explicitly is an error).

    :raises BenchOptionError: ``--ppo-model`` without its row, a policy that cannot be loaded,
        or a policy named like another controller
    """
    opt_row = catalog.POLICY_OPTION_ROW
    chosen = list(catalog.controller_names("bench")) if names is None else list(names)
    if ppo_model is not None and opt_row not in chosen:
        raise BenchOptionError(f"--ppo-model: given, but {opt_row!r} is not among --controllers")
    rows, notes = [], []
    for name in chosen:
        row, option = catalog.CONTROLLERS[name], f"--controllers {name}"
        if name == opt_row and ppo_model is not None:
            row, option = catalog.policy_row(ppo_model), "--ppo-model"
            clash = catalog.policy_name_problem(ppo_model)
            if clash is not None:
                raise BenchOptionError(f"--ppo-model: {clash}")
        problem = row.policy_problem()
        if problem is None:
            rows.append(row)
        elif names is not None or option == "--ppo-model":
            raise BenchOptionError(f"{option}: {problem}")
        else:
            notes.append(f"no shipped policy for {name!r} ({problem}); running without it "
                         f"(give --ppo-model PATH to bench a trained policy)")
    return rows, notes


#: least scored time of an episode after its warm-up, s: a 3-sigma needs data
MIN_SCORED_S = 1.0


def least_steps(warmup_s: float, dt: float) -> int:
    """The shortest episode, control periods, that scores :data:`MIN_SCORED_S` after a warm-up
    of ``warmup_s`` (the one rule of the bench and the campaign: nothing scored is an error).
    """
    return int(math.ceil((warmup_s + MIN_SCORED_S) / dt - 1e-9))


def _check_steps(steps: int | None, scenarios: Sequence[str], sweep: bool, dt: float) -> None:
    """Refuse ``--steps`` that leaves less than :data:`MIN_SCORED_S` after a scenario's warm-up
    (every cell of the tables would be empty).
    """
    if steps is None:
        return
    warm = [(catalog.SCENARIOS[s].scenario().warmup_s, s) for s in scenarios]
    if sweep and any(s in scenarios for s, _ in SWEEP_DIRECTIONS.values()):
        warm.append((SWEEP_WARMUP_S, "the wind sweep"))
    w, name = max(warm)
    need = least_steps(w, dt)
    if steps < need:
        raise BenchOptionError(f"--steps: {steps} control periods ({steps * dt:g} s) leave less "
                               f"than {MIN_SCORED_S:g} s after the {w:g}-s warm-up of {name}; "
                               f"give --steps {need} or more")


def _run_for(budget: Budget, seeds: list[int] | None, steps: int | None, sequential: int | None,
             label: str, dt: float) -> ScenarioRun:
    s = list(range(budget.episodes)) if seeds is None else list(seeds)
    n_steps = int(round(budget.seconds / dt)) if steps is None else steps
    if sequential is None:
        seq = min(budget.sequential, len(s))
    elif sequential > len(s):
        raise BenchOptionError(f"--sequential-episodes: {sequential} is more than the {len(s)} "
                               f"episodes of {label}")
    else:
        seq = sequential
    return ScenarioRun(n_steps, tuple(s), seq)


def _sweep_seeds(seeds: list[int] | None, n: int | None) -> list[int] | None:
    """The sweep points' seeds: the first ``n`` (``--sweep-seeds``) of the seeds given by
    ``--seeds`` (all of them without ``n``), else ``0 .. n-1`` (None: the sweep's default count).

    :raises BenchOptionError: ``n`` is more than the seeds given
    """
    if seeds is None:
        return None if n is None else list(range(n))
    if n is not None and n > len(seeds):
        raise BenchOptionError(f"--sweep-seeds: {n} is more than the {len(seeds)} seeds of --seeds")
    return list(seeds) if n is None else list(seeds[:n])


def build_plan(controllers: Sequence[str] | None = None, scenarios: Sequence[str] | None = None,
               seeds: int | Sequence[str | int] | None = None,
               wind_speeds: Sequence[str | float] | None = None, steps: int | None = None,
               quick: bool = False, ppo_model: str | Path | None = None, randomize: bool = False,
               out: str | Path = "bench_out", figures: bool = True, sweep: bool = True,
               sweep_seeds: int | None = None, sequential_episodes: int | None = None,
               threads: int | None = DEFAULT_THREADS, overwrite: bool = False,
               command: str | None = None, variants: Sequence[str] | None = None,
               jobs: int | None = None) -> BenchPlan:
    """Resolve and validate the bench options (None: the default of the option).

    :param controllers: controller names of the catalog (default :data:`DEFAULT_CONTROLLERS`;
        there, a missing shipped policy is a warning in ``notes`` and its row is left out;
        asked for explicitly, it is an error)
    :param scenarios: scenario names (default :data:`DEFAULT_SCENARIOS`)
    :param seeds: the batched controllers' seeds in every scenario: an int is that many seeds
        from 0 (``--episodes``; the sweep keeps its own count), ints are those seeds (in every
        sweep point too), strings are ``--seeds`` values
        (:func:`parse_seeds`: seeds and ranges); default each scenario's count (:data:`DEFAULT_BUDGETS`, with
        ``quick`` :data:`QUICK_BUDGETS`)
    :param wind_speeds: sweep speeds, km/h (default :func:`default_wind_speeds`, with
        ``quick`` :data:`QUICK_WIND_SPEEDS_KMH`)
    :param steps: episode length of every scenario and sweep point, control periods (default:
        each scenario's)
    :param quick: the short version; options given explicitly still apply
    :param ppo_model: a trained policy (run folder, ``eval/best`` folder or zip) that replaces
        the ``ppo`` row and scores under its own name (:func:`dss14_env.bench.catalog.policy_name`)
    :param randomize: randomised plant parameters (``randomize_params=True``) every episode
    :param out: output folder (checked when the bench starts, before any work)
    :param figures: draw the PNG figures
    :param sweep: run the error-vs-wind sweep (for the selected hold scenarios)
    :param sweep_seeds: episodes per sweep point of the batched controllers (default
        :data:`DEFAULT_SWEEP`, or every seed given as seeds): with seeds given as seeds (not a
        count), the first this many of them, else seeds ``0 .. sweep_seeds-1``
    :param sequential_episodes: episodes of the controllers that run one at a time (the MPC),
        in every scenario and sweep point: the first this many seeds (default: each scenario's)
    :param threads: BLAS threads while running (default 1; None leaves them alone)
    :param overwrite: replace the results of an earlier bench in ``out``
    :param command: the command line, stored in results.json
    :param variants: drive variants whose hold scenarios run too (default
        :data:`DEFAULT_VARIANTS`, with ``quick`` none; empty: none), with
        :data:`VARIANT_CONTROLLERS` among the selected controllers
    :param jobs: worker processes (default :func:`default_jobs`; 1: one process, serially);
        the results are the same for any count
    :raises BenchOptionError: a bad option (the message names it)
    """
    ctrl = _names(controllers, catalog.controller_names(), "--controllers", "controller")
    scen = _names(scenarios, catalog.scenario_names(), "--scenarios", "scenario")
    var = (list(DEFAULT_VARIANTS) if not quick else []) if variants is None else (
        _names(variants, tuple(DRIVE_VARIANTS), "--variants", "drive variant") if variants else [])
    seed_list = _seed_option(seeds)
    speeds = parse_wind_speeds(wind_speeds)
    steps = _count(steps, "--steps", 1, MAX_EPISODE_STEPS)
    sweep_n = _count(sweep_seeds, "--sweep-seeds", 1, MAX_EPISODES)
    seq = _count(sequential_episodes, "--sequential-episodes", 0, MAX_EPISODES)
    threads = _count(threads, "--threads", 1, 2**63 - 1)
    if threads is not None and threads > (os.cpu_count() or 1):
        raise BenchOptionError(f"--threads: {threads} BLAS threads, this machine has "
                               f"{os.cpu_count() or 1} CPUs")
    threads = _count(threads, "--threads", 1, MAX_THREADS)
    jobs = default_jobs() if jobs is None else _count(jobs, "--jobs", 1, MAX_THREADS)
    scen = list(catalog.scenario_names("bench")) if scen is None else scen
    env_kwargs = {"randomize_params": True} if randomize else {}
    dt = control_period(env_kwargs)
    _check_steps(steps, scen, sweep, dt)
    rows, notes = controller_rows(ctrl, ppo_model)
    runs = {s: _run_for(_budget(s, quick), seed_list, steps, seq, s, dt) for s in scen}
    sb = QUICK_SWEEP if quick else DEFAULT_SWEEP
    sweep_run = _run_for(sb, _sweep_seeds(seed_list if seeds is not None and not _is_int(seeds) else None,
                                          sweep_n), steps, seq, "a sweep point", dt)
    directions = [d for d, (s, _) in SWEEP_DIRECTIONS.items() if s in scen] if sweep else []
    variant_run = _run_for(QUICK_VARIANT_RUN if quick else DEFAULT_VARIANT_RUN, seed_list, steps, 0,
                           "a drive variant", dt)
    if var and (randomize or not any(s in scen for s, _ in SWEEP_DIRECTIONS.values())
                or not any(r.name in VARIANT_CONTROLLERS for r in rows)):
        if variants:
            notes.append("--variants ignored: the drive variants run the hold scenarios "
                         f"({', '.join(s for s, _ in SWEEP_DIRECTIONS.values())}) with "
                         f"{', '.join(VARIANT_CONTROLLERS)} on the nominal plant parameters")
        var = []
    if sweep and not directions and speeds is not None:
        anchors = " nor ".join(s for s, _ in SWEEP_DIRECTIONS.values())
        notes.append(f"--wind-speeds ignored: the wind sweep extends the hold scenarios, and "
                     f"neither {anchors} is among --scenarios")
    if speeds is None:
        speeds = list(QUICK_WIND_SPEEDS_KMH if quick else default_wind_speeds())
    return BenchPlan(controllers=[r.name for r in rows], scenarios=scen, runs=runs, wind_speeds_kmh=speeds,
                     sweep_directions=directions, sweep=sweep_run, variants=var, variant_run=variant_run,
                     env_kwargs=env_kwargs, rows=tuple(rows), dt=dt,
                     ppo_model=None if ppo_model is None else str(ppo_model), out=Path(out),
                     overwrite=bool(overwrite), figures=bool(figures), threads=threads, jobs=jobs,
                     quick=bool(quick), notes=notes, command=command)


def sweep_scenario(direction: str, speed_kmh: float, steps: int) -> Scenario:
    """A hold scenario of the wind sweep.

    :param direction: ``"front"`` or ``"side"``
    :param speed_kmh: mean wind speed, km/h
    :param steps: episode length, control periods
    """
    base = catalog.SCENARIOS[SWEEP_DIRECTIONS[direction][0]].scenario()
    return Scenario({**base.env, "wind_speed_kmh": float(speed_kmh)}, int(steps), SWEEP_WARMUP_S,
                    f"hold, {speed_kmh:g} km/h {direction} wind (sweep)")


def sweep_name(direction: str, speed_kmh: float) -> str:
    """Name of a sweep point, e.g. ``hold_front_30kmh``."""
    return f"hold_{direction}_{speed_kmh:g}kmh"


__all__ = ["BenchOptionError", "BenchPlan", "Budget", "DEFAULT_BUDGETS", "DEFAULT_CONTROLLERS",
           "DEFAULT_SCENARIOS", "DEFAULT_SWEEP", "DEFAULT_VARIANTS", "VARIANT_CONTROLLERS", "LOADED_AXES",
           "QUICK_BUDGETS", "QUICK_SWEEP", "ScenarioRun", "SWEEP_DIRECTIONS", "build_plan",
           "MAX_DEFAULT_JOBS", "MIN_SCORED_S", "default_jobs", "check_names", "control_period",
           "controller_rows", "least_steps",
           "parse_episodes", "parse_seeds", "default_wind_speeds", "parse_wind_speeds", "sweep_name",
           "sweep_scenario"]
