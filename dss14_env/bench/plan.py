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
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.bench import runner
from dss14_env.bench.runner import SCENARIOS, Scenario
from dss14_env.envs.config import WIND_SPEED_MAX_KMH

#: control periods per second (the environment's 50 Hz)
STEPS_PER_S = 50


@dataclass(frozen=True)
class Budget:
    """Episode length and counts of one scenario.

    :param seconds: episode length, s
    :param episodes: episodes of the controllers that act on batches (seeds 0, 1, ...)
    :param sequential: episodes of the controllers that run one at a time (the first seeds)
    """

    seconds: float
    episodes: int
    sequential: int


#: the default run: hold scenarios long and many enough for a 95 % half-width <= 5 % of the
#: loaded axis' 3σ for the batched controllers (60-s episodes scatter about 15 % (1 σ) from
#: seed to seed, so 128 of them give about 2-3 %); the MPC gets what fits the 5-minute budget
DEFAULT_BUDGETS: dict[str, Budget] = {
    "hold_front": Budget(60.0, 128, 16),
    "hold_side": Budget(60.0, 128, 16),
    "step": Budget(20.0, 16, 2),      # no wind: episodes differ only in start and quantisation
    "track": Budget(40.0, 128, 6),    # random 30-70 km/h wind and direction: wide by design
    "slew": Budget(50.0, 32, 3),      # the commanded move dominates
}
#: a point of the error-vs-wind sweep (the MPC is left out: the 50 km/h points are the hold
#: scenarios, where it runs)
DEFAULT_SWEEP = Budget(60.0, 32, 0)
#: ``--quick``: the CI smoke test (well under 30 s)
QUICK_BUDGETS: dict[str, Budget] = {
    "hold_front": Budget(15.0, 8, 1),
    "hold_side": Budget(15.0, 8, 1),
    "step": Budget(15.0, 4, 1),
    "track": Budget(10.0, 8, 1),
    "slew": Budget(10.0, 4, 1),
}
QUICK_SWEEP = Budget(15.0, 8, 0)
#: controllers of a run without ``--controllers``
DEFAULT_CONTROLLERS: tuple[str, ...] = ("pi_kp1", "pi_kp0.7", "lqg", "mpc", "ppo", "ppo_plain",
                                         "ppo_residual_lqg")
#: scenarios of a run without ``--scenarios`` (all of :data:`dss14_env.bench.runner.SCENARIOS`)
DEFAULT_SCENARIOS: tuple[str, ...] = ("hold_front", "hold_side", "step", "track", "slew")
#: wind speeds (km/h) of the error-vs-wind sweep without ``--wind-speeds``
DEFAULT_WIND_SPEEDS_KMH: tuple[float, ...] = (30.0, 40.0, 50.0, 60.0, 70.0)
QUICK_WIND_SPEEDS_KMH: tuple[float, ...] = (30.0, 50.0, 70.0)
#: warm-up of a sweep point, s (the hold scenarios')
SWEEP_WARMUP_S = 5.0
#: the sweep's directions, the hold scenario each extends and the axis the wind acts on most
SWEEP_DIRECTIONS: dict[str, tuple[str, str]] = {"front": ("hold_front", "el"),
                                                "side": ("hold_side", "az")}
#: the axis the wind loads per scenario (bold in the tables; the precision target's axis)
LOADED_AXES: dict[str, tuple[str, ...]] = {"hold_front": ("el",), "hold_side": ("az",)}
#: default BLAS threads while running
DEFAULT_THREADS = 1


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

    :param controllers: controller names (runner names or ``"ppo"``)
    :param scenarios: scenario names of :data:`dss14_env.bench.runner.SCENARIOS`
    :param runs: per scenario, its episode length and seeds (:class:`ScenarioRun`)
    :param wind_speeds_kmh: speeds of the error-vs-wind sweep
    :param sweep_directions: ``"front"`` and/or ``"side"`` (those of the selected hold
        scenarios); empty: no sweep
    :param sweep: what a sweep point runs
    :param env_kwargs: environment keys on top of every scenario's
    :param ppo_model: the PPO policy's path (None: the shipped policy), used if ``"ppo"`` runs
    :param out: output folder
    :param overwrite: replace the bench's files in an output folder that has them
    :param figures: draw the PNG figures
    :param threads: BLAS threads while running (None: leave them)
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
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    ppo_model: str | None = None
    out: Path = Path("bench_out")
    overwrite: bool = False
    figures: bool = True
    threads: int | None = DEFAULT_THREADS
    quick: bool = False
    bootstrap_seed: int = 0
    notes: list[str] = field(default_factory=list)
    command: str | None = None

    def scenario(self, name: str) -> Scenario:
        """The runner scenario ``name`` with the plan's episode length."""
        return dataclasses.replace(SCENARIOS[name], steps=self.runs[name].steps)

    def as_dict(self) -> dict[str, Any]:
        """The plan, JSON-ready (the ``bench.config`` entry of results.json)."""
        d = dataclasses.asdict(self)
        d["out"] = str(self.out)
        d["runs"] = {s: {"steps": r.steps, "seconds": r.steps / STEPS_PER_S, "seeds": list(r.seeds),
                         "sequential_seeds": list(r.sequential_seeds),
                         "warmup_s": SCENARIOS[s].warmup_s} for s, r in self.runs.items()}
        d["sweep"] = {"steps": self.sweep.steps, "seconds": self.sweep.steps / STEPS_PER_S,
                      "seeds": list(self.sweep.seeds),
                      "sequential_seeds": list(self.sweep.sequential_seeds), "warmup_s": SWEEP_WARMUP_S}
        d["ppo_policy"] = self.ppo_policy_path() if "ppo" in self.controllers else None
        return d

    def ppo_policy_path(self) -> str:
        """The PPO policy that runs: ``ppo_model`` or the shipped one."""
        if self.ppo_model is not None:
            return str(self.ppo_model)
        from dss14_env.agents.policy import DEFAULT_POLICY
        return str(DEFAULT_POLICY)

    def describe(self) -> str:
        """One line: what the plan runs."""
        parts = [f"{s} {r.steps / STEPS_PER_S:g} s x {len(r.seeds)} (one-at-a-time: {r.sequential})"
                 for s, r in self.runs.items()]
        line = (f"bench: {len(self.controllers)} controllers ({', '.join(self.controllers)}); "
                f"episodes per scenario: {'; '.join(parts)}")
        if self.sweep_directions:
            line += (f"; wind sweep {'/'.join(self.sweep_directions)} at "
                     f"{', '.join(f'{v:g}' for v in self.wind_speeds_kmh)} km/h "
                     f"({self.sweep.steps / STEPS_PER_S:g} s x {len(self.sweep.seeds)}, one-at-a-time: "
                     f"{self.sweep.sequential})")
        if self.env_kwargs:
            line += f"; env {self.env_kwargs}"
        return line


# ------------------------------------------------------------------------------ options
def _names(values: Sequence[str] | None, known: Sequence[str], option: str, what: str
           ) -> list[str] | None:
    """Validate a list of names: known, unique, not empty."""
    if values is None:
        return None
    names = [str(v) for v in values]
    if not names:
        raise BenchOptionError(f"{option}: give at least one {what}")
    for n in names:
        if n not in known:
            near = difflib.get_close_matches(n, known, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise BenchOptionError(f"{option}: unknown {what} {n!r}{hint}; known: {', '.join(known)}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise BenchOptionError(f"{option}: {what} named twice: {', '.join(dup)}")
    return names


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
    """``--seeds`` as on the command line: one value N means the first N seeds (0 .. N-1);
    several values are the seeds themselves.

    :param values: the option's values (strings from the command line, or ints)
    :return: the seeds, or None when the option was not given
    :raises BenchOptionError: not integers, negative, repeated, or a count below 1
    """
    if values is None:
        return None
    ints = []
    for v in values:
        try:
            ints.append(int(str(v), 10))
        except ValueError:
            raise BenchOptionError(f"--seeds: {v!r} is not an integer") from None
    if len(ints) == 1:
        if ints[0] < 1:
            raise BenchOptionError("--seeds: a single value is a count of seeds and must be >= 1")
        return list(range(ints[0]))
    return _check_seeds(ints)


def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _seed_option(seeds: int | Sequence[str | int] | None) -> list[int] | None:
    """build_plan's ``seeds``: an int is a count, a sequence of ints the seeds themselves,
    strings (command-line values) go through :func:`parse_seeds`.
    """
    if seeds is None:
        return None
    if _is_int(seeds):
        return parse_seeds([str(int(seeds))])
    seeds = list(seeds)
    if seeds and all(_is_int(s) for s in seeds):
        return _check_seeds([int(s) for s in seeds])
    return parse_seeds(seeds)


def parse_wind_speeds(values: Sequence[str | float] | None) -> list[float] | None:
    """``--wind-speeds``: mean wind speeds of the sweep, km/h, each in (0, 90] (the
    environment's own bound, :data:`dss14_env.envs.config.WIND_SPEED_MAX_KMH`), sorted.

    :raises BenchOptionError: not numbers, out of range or repeated
    """
    if values is None:
        return None
    if len(values) == 0:
        raise BenchOptionError("--wind-speeds: give at least one speed in km/h (or --no-sweep)")
    speeds = []
    for v in values:
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise BenchOptionError(f"--wind-speeds: {v!r} is not a number (km/h)") from None
        if not (math.isfinite(x) and 0.0 < x <= WIND_SPEED_MAX_KMH):
            raise BenchOptionError(f"--wind-speeds: {v} km/h is outside (0, {WIND_SPEED_MAX_KMH:g}] "
                                   f"km/h, the environment's wind_speed_kmh range "
                                   f"(WIND_SPEED_MAX_KMH)")
        speeds.append(x)
    if len(set(speeds)) != len(speeds):
        raise BenchOptionError(f"--wind-speeds: a speed is repeated: {values}")
    return sorted(speeds)


def _count(value: Any, option: str, low: int, what: str) -> int | None:
    if value is None:
        return None
    if not _is_int(value) or value < low:
        raise BenchOptionError(f"{option}: {what} is an integer >= {low}, got {value!r}")
    return int(value)


def ppo_problem(path: str | Path | None) -> str | None:
    """Why the PPO policy at ``path`` (None: the shipped one) cannot run in the bench, or None
    (:func:`dss14_env.agents.policy.dss14_policy_problem`: the folder's layout, a foreign
    pickled policy refused, its files loaded, and its observation and action sizes those of a
    DSS14 environment).
    """
    from dss14_env.agents.policy import DEFAULT_POLICY, dss14_policy_problem

    return dss14_policy_problem(DEFAULT_POLICY if path is None else Path(path))


#: least scored time of an episode after its warm-up, s: a 3-sigma needs data
MIN_SCORED_S = 1.0


def _check_steps(steps: int | None, scenarios: Sequence[str], sweep: bool) -> None:
    """Refuse ``--steps`` that leaves less than :data:`MIN_SCORED_S` after a scenario's warm-up
    (every cell of the tables would be empty).
    """
    if steps is None:
        return
    warm = [(SCENARIOS[s].warmup_s, s) for s in scenarios]
    if sweep and any(s.startswith("hold") for s in scenarios):
        warm.append((SWEEP_WARMUP_S, "the wind sweep"))
    w, name = max(warm)
    need = int(round((w + MIN_SCORED_S) * STEPS_PER_S))
    if steps < need:
        raise BenchOptionError(f"--steps: {steps} control periods ({steps / STEPS_PER_S:g} s) leave "
                               f"less than {MIN_SCORED_S:g} s after the {w:g}-s warm-up of {name}; "
                               f"give --steps {need} or more")


def _run_for(budget: Budget, seeds: list[int] | None, steps: int | None, sequential: int | None,
             label: str) -> ScenarioRun:
    s = list(range(budget.episodes)) if seeds is None else list(seeds)
    n_steps = int(round(budget.seconds * STEPS_PER_S)) if steps is None else steps
    if sequential is None:
        seq = min(budget.sequential, len(s))
    elif sequential > len(s):
        raise BenchOptionError(f"--sequential-episodes: {sequential} is more than the {len(s)} "
                               f"episodes of {label}")
    else:
        seq = sequential
    return ScenarioRun(n_steps, tuple(s), seq)


def build_plan(controllers: Sequence[str] | None = None, scenarios: Sequence[str] | None = None,
               seeds: int | Sequence[str | int] | None = None,
               wind_speeds: Sequence[str | float] | None = None, steps: int | None = None,
               quick: bool = False, ppo_model: str | Path | None = None, randomize: bool = False,
               out: str | Path = "bench_out", figures: bool = True, sweep: bool = True,
               sweep_seeds: int | None = None, sequential_episodes: int | None = None,
               threads: int | None = DEFAULT_THREADS, overwrite: bool = False,
               command: str | None = None) -> BenchPlan:
    """Resolve and validate the bench options (None: the default of the option).

    :param controllers: controller names (default :data:`DEFAULT_CONTROLLERS`; there, a
        missing shipped PPO policy is a warning in ``notes`` and PPO is left out; asked for
        explicitly, it is an error)
    :param scenarios: scenario names (default :data:`DEFAULT_SCENARIOS`)
    :param seeds: the batched controllers' seeds in every scenario: an int is that many seeds
        from 0, ints are those seeds, strings are ``--seeds`` values (:func:`parse_seeds`: one
        value is a count); default each scenario's count (:data:`DEFAULT_BUDGETS`, with
        ``quick`` :data:`QUICK_BUDGETS`)
    :param wind_speeds: sweep speeds, km/h (default :data:`DEFAULT_WIND_SPEEDS_KMH`, with
        ``quick`` :data:`QUICK_WIND_SPEEDS_KMH`)
    :param steps: episode length of every scenario and sweep point, control periods (default:
        each scenario's)
    :param quick: the short version; options given explicitly still apply
    :param ppo_model: PPO policy (run folder, ``eval/best`` folder or zip; default the shipped
        one, :data:`dss14_env.agents.policy.DEFAULT_POLICY`)
    :param randomize: randomised plant parameters (``randomize_params=True``) every episode
    :param out: output folder (checked when the bench starts, before any work)
    :param figures: draw the PNG figures
    :param sweep: run the error-vs-wind sweep (for the selected hold scenarios)
    :param sweep_seeds: episodes per sweep point of the batched controllers (default
        :data:`DEFAULT_SWEEP`)
    :param sequential_episodes: episodes of the controllers that run one at a time (the MPC),
        in every scenario and sweep point: the first this many seeds (default: each scenario's)
    :param threads: BLAS threads while running (default 1; None leaves them alone)
    :param overwrite: replace the results of an earlier bench in ``out``
    :param command: the command line, stored in results.json
    :raises BenchOptionError: a bad option (the message names it)
    """
    known_ctrl = sorted(runner.CONTROLLERS) + ["ppo"]
    ctrl = _names(controllers, known_ctrl, "--controllers", "controller")
    scen = _names(scenarios, sorted(SCENARIOS), "--scenarios", "scenario")
    seed_list = _seed_option(seeds)
    speeds = parse_wind_speeds(wind_speeds)
    steps = _count(steps, "--steps", 1, "the episode length")
    sweep_n = _count(sweep_seeds, "--sweep-seeds", 1, "the number of episodes per sweep point")
    seq = _count(sequential_episodes, "--sequential-episodes", 0, "the number of episodes")
    threads = _count(threads, "--threads", 1, "the number of BLAS threads")
    if threads is not None and threads > (os.cpu_count() or 1):
        raise BenchOptionError(f"--threads: {threads} BLAS threads, this machine has "
                               f"{os.cpu_count() or 1} CPUs")
    notes: list[str] = []
    explicit_ppo = controllers is not None and "ppo" in ctrl
    if ctrl is None:
        ctrl = list(DEFAULT_CONTROLLERS)
    if ppo_model is not None and "ppo" not in ctrl:
        raise BenchOptionError("--ppo-model: given, but 'ppo' is not among --controllers")
    if "ppo" in ctrl:
        problem = ppo_problem(ppo_model)
        if problem is not None:
            if explicit_ppo or ppo_model is not None:
                opt = "--ppo-model" if ppo_model is not None else "--controllers ppo"
                raise BenchOptionError(f"{opt}: {problem}")
            notes.append(f"no shipped PPO policy ({problem}); running without 'ppo' "
                         f"(give --ppo-model PATH to bench a trained policy)")
            ctrl = [c for c in ctrl if c != "ppo"]
    scen = list(DEFAULT_SCENARIOS) if scen is None else scen
    _check_steps(steps, scen, sweep)
    budgets = QUICK_BUDGETS if quick else DEFAULT_BUDGETS
    runs = {s: _run_for(budgets[s], seed_list, steps, seq, s) for s in scen}
    sb = QUICK_SWEEP if quick else DEFAULT_SWEEP
    sweep_run = _run_for(sb, list(range(sweep_n)) if sweep_n is not None else None, steps, seq,
                         "a sweep point")
    directions = [d for d, (s, _) in SWEEP_DIRECTIONS.items() if s in scen] if sweep else []
    if sweep and not directions and speeds is not None:
        notes.append("--wind-speeds ignored: the wind sweep extends the hold scenarios, and "
                     "neither hold_front nor hold_side is among --scenarios")
    if speeds is None:
        speeds = list(QUICK_WIND_SPEEDS_KMH if quick else DEFAULT_WIND_SPEEDS_KMH)
    return BenchPlan(controllers=ctrl, scenarios=scen, runs=runs, wind_speeds_kmh=speeds,
                     sweep_directions=directions, sweep=sweep_run,
                     env_kwargs={"randomize_params": True} if randomize else {},
                     ppo_model=None if ppo_model is None else str(ppo_model), out=Path(out),
                     overwrite=bool(overwrite), figures=bool(figures), threads=threads,
                     quick=bool(quick), notes=notes, command=command)


def sweep_scenario(direction: str, speed_kmh: float, steps: int) -> Scenario:
    """A hold scenario of the wind sweep.

    :param direction: ``"front"`` or ``"side"``
    :param speed_kmh: mean wind speed, km/h
    :param steps: episode length, control periods
    """
    base = SCENARIOS[SWEEP_DIRECTIONS[direction][0]]
    return Scenario({**base.env, "wind_speed_kmh": float(speed_kmh)}, int(steps), SWEEP_WARMUP_S,
                    f"hold, {speed_kmh:g} km/h {direction} wind (sweep)")


def sweep_name(direction: str, speed_kmh: float) -> str:
    """Name of a sweep point, e.g. ``hold_front_30kmh``."""
    return f"hold_{direction}_{speed_kmh:g}kmh"


__all__ = ["BenchOptionError", "BenchPlan", "Budget", "DEFAULT_BUDGETS", "DEFAULT_CONTROLLERS",
           "DEFAULT_SCENARIOS", "DEFAULT_SWEEP", "DEFAULT_WIND_SPEEDS_KMH", "LOADED_AXES",
           "QUICK_BUDGETS", "QUICK_SWEEP", "ScenarioRun", "SWEEP_DIRECTIONS", "build_plan",
           "parse_seeds", "parse_wind_speeds", "ppo_problem", "sweep_name", "sweep_scenario"]
