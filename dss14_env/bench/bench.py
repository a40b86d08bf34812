"""``dss14 bench``: every controller through the one runner, on the same scenarios and seeds.

The bench is a thin layer over :func:`dss14_env.bench.runner.run`: it turns the command-line options
into a :class:`BenchPlan` (:func:`build_plan`, which validates every option and names the one
that is wrong), runs the plan's controllers on its scenarios and seeds with a progress bar
(:func:`run_plan`), then runs the error-vs-wind sweep of the hold scenarios, and writes
``results.json``, ``results.md`` and four PNG figures (:func:`write_results`,
:func:`draw_figures`).  :func:`bench` does all of it::

    from dss14_env.bench.bench import build_plan, bench
    out = bench(build_plan(controllers=["pi_kp1", "lqg"], quick=True, out="bench_out"))
    print(out["main_table"])

Controllers are the runner's (:data:`dss14_env.bench.runner.CONTROLLERS`) plus ``"ppo"``, a trained
PPO policy loaded by :func:`dss14_env.agents.policy.load_policy` (the policy shipped with the package
unless ``ppo_model`` names another); torch is imported only when ``"ppo"`` runs.

``docs/bench.md`` describes the options, the output files and how to read them.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import os
import platform
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from dss14_env.bench import runner
from dss14_env.bench.runner import SCENARIOS, Scenario

#: controllers of a run without ``--controllers``
DEFAULT_CONTROLLERS: tuple[str, ...] = ("pi_kp1", "pi_kp0.7", "lqg", "mpc", "ppo")
#: scenarios of a run without ``--scenarios`` (all of :data:`dss14_env.bench.runner.SCENARIOS`)
DEFAULT_SCENARIOS: tuple[str, ...] = ("hold_front", "hold_side", "step", "track", "slew")
#: seeds of a run without ``--seeds``
DEFAULT_SEEDS: tuple[int, ...] = (0, 1)
#: wind speeds (km/h) of the error-vs-wind sweep without ``--wind-speeds``
DEFAULT_WIND_SPEEDS_KMH: tuple[float, ...] = (30.0, 40.0, 50.0, 60.0, 70.0)
#: episode lengths that differ from the scenario's (control periods): the track runs 40 s
#: instead of 60 s so that the default run stays within 5 minutes on 2 cores
DEFAULT_STEPS: dict[str, int] = {"track": 2000}
#: episode length of a sweep point (control periods; 20 s at 50 Hz) and its warm-up, s
SWEEP_STEPS = 1000
SWEEP_WARMUP_S = 5.0
#: the sweep runs on the first this many seeds of the plan (``--sweep-seeds``)
SWEEP_SEEDS = 1
#: ``--quick``: one seed, shorter episodes, three wind speeds
QUICK_SEEDS: tuple[int, ...] = (0,)
QUICK_WIND_SPEEDS_KMH: tuple[float, ...] = (30.0, 50.0, 70.0)
QUICK_STEPS: dict[str, int] = {"hold_front": 500, "hold_side": 500, "step": 750, "track": 500,
                               "slew": 500}
QUICK_SWEEP_STEPS = 500
#: the sweep's directions, the hold scenario each extends and the axis the wind acts on most
SWEEP_DIRECTIONS: dict[str, tuple[str, str]] = {"front": ("hold_front", "el"),
                                                "side": ("hold_side", "az")}
#: the axis (or axes) that matter per scenario, shown in bold in the main table
DOMINANT_AXES: dict[str, tuple[str, ...]] = {"hold_front": ("el",), "hold_side": ("az",)}
#: scenarios whose pointing-error output is an error: the environment's pointing outputs are
#: the dish's el / xel angles relative to the start, so with a moving command (step, track,
#: slew) they contain the motion itself; results.md shows them for the hold scenarios only
POINTING_SCENARIOS = ("hold_front", "hold_side")
#: the figures :func:`draw_figures` writes
FIGURES = ("errors_3sigma.png", "hold_time_histories.png", "step_responses.png", "wind_sweep.png")
AXES = ("az", "el")
#: distributions whose versions go into results.json
VERSIONED = ("numpy", "scipy", "gymnasium", "stable-baselines3", "torch", "cvxpy", "dss14-env")


class BenchOptionError(ValueError):
    """A bad bench option; the message starts with the option's name."""


@dataclass
class BenchPlan:
    """Everything a bench run needs, resolved and validated (:func:`build_plan`).

    :param controllers: controller names (runner names or ``"ppo"``)
    :param scenarios: scenario names of :data:`dss14_env.bench.runner.SCENARIOS`
    :param seeds: episode seeds, the same for every controller and scenario
    :param steps: episode length per scenario, control periods
    :param wind_speeds_kmh: speeds of the error-vs-wind sweep
    :param sweep_directions: ``"front"`` and/or ``"side"``: the sweep's directions (those of
        the selected hold scenarios); empty: no sweep
    :param sweep_steps: episode length of a sweep point, control periods
    :param sweep_seeds: the sweep's seeds (the first of ``seeds``)
    :param env_kwargs: environment keys on top of every scenario's
    :param ppo_model: the PPO policy's path (None: the shipped policy), used if ``"ppo"`` runs
    :param out: output folder
    :param figures: draw the PNG figures
    :param quick: the plan came from ``--quick`` (for the record)
    :param notes: warnings found while building the plan (printed, stored in results.json)
    :param command: the command line, for the record
    """

    controllers: list[str]
    scenarios: list[str]
    seeds: list[int]
    steps: dict[str, int]
    wind_speeds_kmh: list[float]
    sweep_directions: list[str]
    sweep_steps: int
    sweep_seeds: list[int]
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    ppo_model: str | None = None
    out: Path = Path("bench_out")
    figures: bool = True
    quick: bool = False
    notes: list[str] = field(default_factory=list)
    command: str | None = None

    @property
    def n_main_episodes(self) -> int:
        """Episodes of the controller x scenario x seed grid."""
        return len(self.controllers) * len(self.scenarios) * len(self.seeds)

    @property
    def n_sweep_episodes(self) -> int:
        """Episodes of the wind sweep (an upper bound: points shared with the main grid are
        reused, :func:`run_plan`)."""
        return (len(self.controllers) * len(self.sweep_directions) * len(self.wind_speeds_kmh)
                * len(self.sweep_seeds))

    def as_dict(self) -> dict[str, Any]:
        """The plan, JSON-ready (the ``bench.config`` entry of results.json)."""
        d = dataclasses.asdict(self)
        d["out"] = str(self.out)
        d["ppo_policy"] = self.ppo_policy_path() if "ppo" in self.controllers else None
        d["warmup_s"] = {s: SCENARIOS[s].warmup_s for s in self.scenarios}
        d["sweep_warmup_s"] = SWEEP_WARMUP_S
        return d

    def ppo_policy_path(self) -> str:
        """The PPO policy that runs: ``ppo_model`` or the shipped one."""
        if self.ppo_model is not None:
            return str(self.ppo_model)
        from dss14_env.agents.policy import DEFAULT_POLICY
        return str(DEFAULT_POLICY)

    def describe(self) -> str:
        """One line: what the plan runs."""
        line = (f"bench: {len(self.controllers)} controllers ({', '.join(self.controllers)}) x "
                f"{len(self.scenarios)} scenarios x {len(self.seeds)} seeds = "
                f"{self.n_main_episodes} episodes")
        if self.sweep_directions:
            line += (f"; wind sweep {'/'.join(self.sweep_directions)} at "
                     f"{', '.join(f'{v:g}' for v in self.wind_speeds_kmh)} km/h "
                     f"(<= {self.n_sweep_episodes} episodes of {self.sweep_steps} steps, seeds "
                     f"{self.sweep_seeds})")
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


def _seed_option(seeds: int | Sequence[str | int] | None) -> list[int] | None:
    """build_plan's ``seeds``: an int is a count, a sequence of ints the seeds themselves,
    strings (command-line values) go through :func:`parse_seeds`."""
    if seeds is None:
        return None
    if isinstance(seeds, (int, np.integer)) and not isinstance(seeds, bool):
        return parse_seeds([str(int(seeds))])
    seeds = list(seeds)
    if seeds and all(isinstance(s, (int, np.integer)) and not isinstance(s, bool) for s in seeds):
        return _check_seeds([int(s) for s in seeds])
    return parse_seeds(seeds)


def parse_wind_speeds(values: Sequence[str | float] | None) -> list[float] | None:
    """``--wind-speeds``: mean wind speeds of the sweep, km/h, each in (0, 150], sorted.

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
        if not (math.isfinite(x) and 0.0 < x <= 150.0):
            raise BenchOptionError(f"--wind-speeds: speeds are in km/h, > 0 and <= 150, got {v}")
        speeds.append(x)
    if len(set(speeds)) != len(speeds):
        raise BenchOptionError(f"--wind-speeds: a speed is repeated: {values}")
    return sorted(speeds)


def _ppo_problem(path: str | Path | None) -> str | None:
    """Why the PPO policy at ``path`` (None: the shipped one) cannot be loaded, or None."""
    from dss14_env.agents.policy import DEFAULT_POLICY, _model_paths
    try:
        _model_paths(DEFAULT_POLICY if path is None else path)
    except ValueError as exc:
        return str(exc)
    return None


def build_plan(controllers: Sequence[str] | None = None, scenarios: Sequence[str] | None = None,
               seeds: int | Sequence[str | int] | None = None,
               wind_speeds: Sequence[str | float] | None = None, steps: int | None = None,
               quick: bool = False, ppo_model: str | Path | None = None, randomize: bool = False,
               out: str | Path = "bench_out", figures: bool = True, sweep: bool = True,
               sweep_seeds: int | None = None, command: str | None = None) -> BenchPlan:
    """Resolve and validate the bench options (None: the default of the option).

    :param controllers: controller names (default :data:`DEFAULT_CONTROLLERS`; there, a
        missing shipped PPO policy is a warning in ``notes`` and PPO is left out; asked for
        explicitly, it is an error)
    :param scenarios: scenario names (default :data:`DEFAULT_SCENARIOS`)
    :param seeds: an int: that many seeds from 0; ints: those seeds; strings: ``--seeds``
        values (:func:`parse_seeds`: one value is a count); default :data:`DEFAULT_SEEDS`,
        with ``quick`` :data:`QUICK_SEEDS`
    :param wind_speeds: sweep speeds, km/h (default :data:`DEFAULT_WIND_SPEEDS_KMH`, with
        ``quick`` :data:`QUICK_WIND_SPEEDS_KMH`)
    :param steps: episode length of every scenario and sweep point (default: the scenario's
        or :data:`DEFAULT_STEPS`, with ``quick`` :data:`QUICK_STEPS`)
    :param quick: the short version (one seed, shorter episodes, three wind speeds); options
        given explicitly still apply
    :param ppo_model: PPO policy (run folder, ``eval/best`` folder or zip; default the shipped
        one, :data:`dss14_env.agents.policy.DEFAULT_POLICY`)
    :param randomize: randomised plant parameters (``randomize_params=True``) every episode
    :param out: output folder
    :param figures: draw the PNG figures
    :param sweep: run the error-vs-wind sweep (for the selected hold scenarios)
    :param sweep_seeds: the sweep runs on the first this many seeds (default
        :data:`SWEEP_SEEDS`, at most all of them)
    :param command: the command line, stored in results.json
    :raises BenchOptionError: a bad option (the message names it)
    """
    known_ctrl = sorted(runner.CONTROLLERS) + ["ppo"]
    ctrl = _names(controllers, known_ctrl, "--controllers", "controller")
    scen = _names(scenarios, sorted(SCENARIOS), "--scenarios", "scenario")
    seed_list = _seed_option(seeds)
    speeds = parse_wind_speeds(wind_speeds)
    if steps is not None and (isinstance(steps, bool) or int(steps) != steps or steps < 1):
        raise BenchOptionError(f"--steps: the episode length is a positive integer, got {steps!r}")
    notes: list[str] = []
    explicit_ppo = controllers is not None and "ppo" in ctrl
    if ctrl is None:
        ctrl = list(DEFAULT_CONTROLLERS)
    if ppo_model is not None and "ppo" not in ctrl:
        raise BenchOptionError("--ppo-model: given, but 'ppo' is not among --controllers")
    if "ppo" in ctrl:
        problem = _ppo_problem(ppo_model)
        if problem is not None:
            if explicit_ppo or ppo_model is not None:
                opt = "--ppo-model" if ppo_model is not None else "--controllers ppo"
                raise BenchOptionError(f"{opt}: {problem}")
            notes.append(f"no shipped PPO policy ({problem}); running without 'ppo' "
                         f"(give --ppo-model PATH to bench a trained policy)")
            ctrl = [c for c in ctrl if c != "ppo"]
    scen = list(DEFAULT_SCENARIOS) if scen is None else scen
    seed_list = list(QUICK_SEEDS if quick else DEFAULT_SEEDS) if seed_list is None else seed_list
    if sweep_seeds is not None and (isinstance(sweep_seeds, bool) or int(sweep_seeds) != sweep_seeds
                                    or not 1 <= sweep_seeds <= len(seed_list)):
        raise BenchOptionError(f"--sweep-seeds: a count from 1 to the number of seeds "
                               f"({len(seed_list)}), got {sweep_seeds!r}")
    n_sweep_seeds = min(SWEEP_SEEDS, len(seed_list)) if sweep_seeds is None else int(sweep_seeds)
    if steps is not None:
        step_map = {s: int(steps) for s in scen}
        sweep_steps = int(steps)
    elif quick:
        step_map = {s: QUICK_STEPS.get(s, SCENARIOS[s].steps) for s in scen}
        sweep_steps = QUICK_SWEEP_STEPS
    else:
        step_map = {s: DEFAULT_STEPS.get(s, SCENARIOS[s].steps) for s in scen}
        sweep_steps = SWEEP_STEPS
    directions = [d for d, (s, _) in SWEEP_DIRECTIONS.items() if s in scen] if sweep else []
    if sweep and not directions and speeds is not None:
        notes.append("--wind-speeds ignored: the wind sweep extends the hold scenarios, and "
                     "neither hold_front nor hold_side is among --scenarios")
    if speeds is None:
        speeds = list(QUICK_WIND_SPEEDS_KMH if quick else DEFAULT_WIND_SPEEDS_KMH)
    return BenchPlan(controllers=ctrl, scenarios=scen, seeds=seed_list, steps=step_map,
                     wind_speeds_kmh=speeds, sweep_directions=directions, sweep_steps=sweep_steps,
                     sweep_seeds=seed_list[:n_sweep_seeds],
                     env_kwargs={"randomize_params": True} if randomize else {},
                     ppo_model=None if ppo_model is None else str(ppo_model), out=Path(out),
                     figures=bool(figures), quick=bool(quick), notes=notes, command=command)


# ------------------------------------------------------------------------------ running
def ppo_factory(path: str | Path | None = None) -> Callable[[Any], Any]:
    """Factory of the ``"ppo"`` controller: :func:`dss14_env.agents.policy.load_policy` on the env.

    :param path: the policy (None: the shipped one)
    """
    def make(env: Any) -> Any:
        from dss14_env.agents.policy import load_policy
        return load_policy(path, env=env)
    return make


def _controller_entries(plan: BenchPlan) -> list[Any]:
    """The runner's controller arguments: names, and a (name, factory) pair for PPO."""
    return [("ppo", ppo_factory(plan.ppo_model)) if c == "ppo" else c for c in plan.controllers]


def sweep_scenario(direction: str, speed_kmh: float, steps: int) -> Scenario:
    """A hold scenario of the wind sweep.

    :param direction: ``"front"`` or ``"side"``
    :param speed_kmh: mean wind speed, km/h
    :param steps: episode length, control periods
    """
    return Scenario({"scenario": "hold", "wind_speed_kmh": float(speed_kmh),
                     "wind_direction": direction}, int(steps), SWEEP_WARMUP_S,
                    f"hold, {speed_kmh:g} km/h {direction} wind (sweep)")


def sweep_name(direction: str, speed_kmh: float) -> str:
    """Name of a sweep point, e.g. ``hold_front_30kmh``."""
    return f"hold_{direction}_{speed_kmh:g}kmh"


def _main_scenarios(plan: BenchPlan) -> list[tuple[str, Scenario]]:
    return [(s, dataclasses.replace(SCENARIOS[s], steps=plan.steps[s])) for s in plan.scenarios]


def _sweep_points(plan: BenchPlan) -> list[tuple[str, str, float, Scenario, str | None]]:
    """(name, direction, speed, scenario, main scenario it equals or None) per sweep point
    (equal: same environment keys, length and warm-up, and the sweep runs on all seeds)."""
    main = dict(_main_scenarios(plan)) if plan.sweep_seeds == plan.seeds else {}
    pts = []
    for d in plan.sweep_directions:
        for v in plan.wind_speeds_kmh:
            sc = sweep_scenario(d, v, plan.sweep_steps)
            same = next((n for n, m in main.items() if dict(m.env) == dict(sc.env)
                         and m.steps == sc.steps and m.warmup_s == sc.warmup_s), None)
            pts.append((sweep_name(d, v), d, v, sc, same))
    return pts


def _progress(bar: Any) -> Callable[[str], None]:
    """Runner progress callback: one tick per episode, labelled controller / scenario / seed."""
    def tick(line: str) -> None:
        head, _, tail = line.partition(":")
        bar.set_description_str(" ".join(head.split()).replace(" seed ", " s"), refresh=False)
        bar.set_postfix_str(tail.strip(), refresh=False)
        bar.update(1)
    return tick


def run_plan(plan: BenchPlan, progress: bool = True) -> dict[str, Any]:
    """Run the plan through :func:`dss14_env.bench.runner.run`: the main grid (with traces) and the
    wind sweep (sweep points equal to a main scenario are taken from it, not rerun).

    :param plan: the plan (:func:`build_plan`)
    :param progress: show a tqdm progress bar (stderr), one tick per episode
    :return: ``{"main": runner result (episodes with ``trace``), "sweep": runner result of the
        sweep points or None, "sweep_points": [...], "wall_time_s": {...}}``
    """
    from tqdm.auto import tqdm

    ctrls = _controller_entries(plan)
    points = _sweep_points(plan)
    to_run = [(n, sc) for n, _, _, sc, same in points if same is None]
    total = plan.n_main_episodes + len(plan.controllers) * len(to_run) * len(plan.sweep_seeds)
    t0 = time.perf_counter()
    with tqdm(total=total, unit="ep", disable=not progress, dynamic_ncols=True,
              desc="building the model") as bar:
        cb = _progress(bar)
        main = runner.run(ctrls, _main_scenarios(plan), plan.seeds, plan.env_kwargs,
                          progress=cb, record=True)
        t1 = time.perf_counter()
        sweep = (runner.run(ctrls, to_run, plan.sweep_seeds, plan.env_kwargs, progress=cb)
                 if to_run else None)
    t2 = time.perf_counter()
    return {"main": main, "sweep": sweep,
            "sweep_points": [(n, d, v, same) for n, d, v, _, same in points],
            "wall_time_s": {"main": t1 - t0, "sweep": t2 - t1}}


# ------------------------------------------------------------------------------ results
def package_versions() -> dict[str, str | None]:
    """Versions of Python and the packages the results depend on (None: not installed)."""
    from importlib import metadata

    out: dict[str, str | None] = {"python": platform.python_version()}
    for dist in VERSIONED:
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def _median(x: Mapping[str, Any]) -> float:
    return float(x["median"])


def wind_sweep_curves(plan: BenchPlan, ran: Mapping[str, Any]) -> dict[str, Any]:
    """The sweep per direction: the wind's axis' 3-sigma (median, min, max over seeds) per
    controller and speed, and the yardstick's analytic expected 3-sigma.

    :param plan: the plan
    :param ran: :func:`run_plan`'s result
    """
    main, sweep = ran["main"], ran["sweep"]
    curves: dict[str, Any] = {}
    for d in plan.sweep_directions:
        axis = SWEEP_DIRECTIONS[d][1]
        i = AXES.index(axis)
        yard, ctrl = [], {c: {"median": [], "min": [], "max": []} for c in plan.controllers}
        for name, dd, _, same in ran["sweep_points"]:
            if dd != d:
                continue
            src, key = (main, same) if same is not None else (sweep, name)
            ref = src["yardstick"].get(key)
            yard.append(None if ref is None else float(ref["three_sigma_mdeg"][i]))
            for c in plan.controllers:
                ts = src["summary"][c][key]["servo_error_mdeg"][axis]["three_sigma"]
                for stat in ("median", "min", "max"):
                    ctrl[c][stat].append(float(ts[stat]))
        curves[d] = {"axis": axis, "speeds_kmh": list(plan.wind_speeds_kmh),
                     "yardstick_three_sigma_mdeg": yard, "three_sigma_mdeg": ctrl}
    return curves


def assemble_results(plan: BenchPlan, ran: Mapping[str, Any], wall_time_s: float) -> dict[str, Any]:
    """results.json's content (no time histories).

    :param plan: the plan
    :param ran: :func:`run_plan`'s result
    :param wall_time_s: the whole bench's wall time so far, s
    """
    main = ran["main"]
    episodes = [{k: v for k, v in ep.items() if k != "trace"} for ep in main["episodes"]]
    sweep: dict[str, Any] | None = None
    if plan.sweep_directions:
        s = ran["sweep"]
        sweep = {"speeds_kmh": list(plan.wind_speeds_kmh), "directions": list(plan.sweep_directions),
                 "steps": plan.sweep_steps, "warmup_s": SWEEP_WARMUP_S, "seeds": list(plan.sweep_seeds),
                 "points": {n: {"direction": d, "speed_kmh": v, "same_as": same}
                            for n, d, v, same in ran["sweep_points"]},
                 "curves": wind_sweep_curves(plan, ran),
                 "summary": s["summary"] if s else {}, "yardstick": s["yardstick"] if s else {},
                 "episodes": s["episodes"] if s else []}
    return {
        "bench": {"command": plan.command, "config": plan.as_dict(), "notes": list(plan.notes),
                  "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                  "wall_time_s": {**ran["wall_time_s"], "total": wall_time_s},
                  "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count()}},
        "versions": package_versions(),
        "meta": main["meta"],
        "summary": main["summary"],
        "yardstick": main["yardstick"],
        "episodes": episodes,
        "wind_sweep": sweep,
    }


# ------------------------------------------------------------------------------ markdown
def fmt(x: Any, digits: int = 3) -> str:
    """A number for the tables: ``—`` for None/NaN, ``∞``, integers as they are, else
    ``digits`` significant figures (no exponent; numbers below 0.01 with 4 decimals)."""
    if x is None:
        return "—"
    if isinstance(x, (int, np.integer)) and not isinstance(x, bool):
        return str(int(x))
    x = float(x)
    if math.isnan(x):
        return "—"
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    if x == 0:
        return "0"
    if abs(x) >= 10 ** (digits - 1):
        return f"{x:.0f}"
    if abs(x) < 0.01:
        return f"{x:.4f}"
    return f"{x:#.{digits}g}".rstrip(".")


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _ts(s: Mapping[str, Any], key: str, axis: str, stat: str = "three_sigma") -> float:
    return _median(s[key][axis][stat])


def _pair(s: Mapping[str, Any], scen: str, key: str = "servo_error_mdeg",
          stat: str = "three_sigma") -> str:
    cells = []
    for ax in AXES:
        v = fmt(_ts(s, key, ax, stat))
        cells.append(f"**{v}**" if ax in DOMINANT_AXES.get(scen, ()) else v)
    return " / ".join(cells)


def main_table(results: Mapping[str, Any]) -> str:
    """The main table: 3-sigma servo error az / el per controller and scenario (median over
    seeds; the wind's axis in bold), the dominant axis over the yardstick, and the yardstick's
    analytic expected value."""
    summ, yard = results["summary"], results["yardstick"]
    ctrls, scens = results["meta"]["controllers"], results["meta"]["scenarios"]
    ratio_cols = [(s, ax) for s in scens for ax in DOMINANT_AXES.get(s, ()) if s in yard]
    header = (["controller"] + [f"{s} az / el" for s in scens]
              + [f"{s} {ax} ÷ yardstick" for s, ax in ratio_cols])
    rows = []
    for c in ctrls:
        r = [c] + [_pair(summ[c][s], s) for s in scens]
        r += [fmt(summ[c][s].get("vs_yardstick", {}).get(ax), 2) for s, ax in ratio_cols]
        rows.append(r)
    if yard:
        r = ["yardstick (analytic)"]
        for s in scens:
            if s in yard:
                v = [fmt(x) for x in yard[s]["three_sigma_mdeg"]]
                v = [f"**{x}**" if ax in DOMINANT_AXES.get(s, ()) else x for x, ax in zip(v, AXES)]
                r.append(" / ".join(v))
            else:
                r.append("—")
        rows.append(r + ["1"] * len(ratio_cols))
    return _table(header, rows)


def error_table(results: Mapping[str, Any]) -> str:
    """Detail: servo errors (3-sigma, rms, max), true pointing errors and yardstick ratios per
    controller and scenario (medians over seeds)."""
    summ = results["summary"]
    header = ["controller", "scenario", "3σ az", "3σ el", "rms az", "rms el", "max az", "max el",
              "pointing 3σ el", "pointing 3σ xel", "÷ yardstick az", "÷ yardstick el"]
    rows = []
    for c in results["meta"]["controllers"]:
        for s in results["meta"]["scenarios"]:
            x = summ[c][s]
            vy = x.get("vs_yardstick", {})
            rows.append([c, s] + [fmt(_ts(x, "servo_error_mdeg", ax, st))
                                  for st in ("three_sigma", "rms", "max") for ax in AXES]
                        + [fmt(_ts(x, "pointing_error_mdeg", ax)) if s in POINTING_SCENARIOS
                           else "—" for ax in ("el", "xel")]
                        + [fmt(vy.get(ax), 2) for ax in AXES])
    return _table(header, rows)


def command_table(results: Mapping[str, Any]) -> str:
    """Detail: commands, limiter hits, controller time and health per controller and scenario."""
    summ = results["summary"]
    header = ["controller", "scenario", "peak rate az / el (°/s)", "peak accel az / el (°/s²)",
              "limit hits rate / accel", "act() median / p95 (ms)", "fallbacks", "failures",
              "terminated"]
    rows = []
    for c in results["meta"]["controllers"]:
        for s in results["meta"]["scenarios"]:
            x = summ[c][s]
            rc = x["rate_command_deg_s"]
            rows.append([c, s,
                         " / ".join(fmt(_median(rc[ax]["peak"])) for ax in AXES),
                         " / ".join(fmt(_median(rc[ax]["peak_accel_deg_s2"])) for ax in AXES),
                         f"{x['limit_hits']['rate']} / {x['limit_hits']['accel']}",
                         " / ".join(fmt(_median(x["controller_time_ms"][k]), 2)
                                    for k in ("median", "p95")),
                         str(x["fallbacks"]), str(x["failures"]), str(x["terminated"])])
    return _table(header, rows)


def step_table(results: Mapping[str, Any], scenario: str = "step") -> str | None:
    """Step response per controller: overshoot and 2 % settling time (median over seeds)."""
    if scenario not in results["meta"]["scenarios"]:
        return None
    header = ["controller", "overshoot az / el (%)", "2 % settling az / el (s)",
              "peak accel az / el (°/s²)", "limit hits rate / accel"]
    rows = []
    for c in results["meta"]["controllers"]:
        x = results["summary"][c][scenario]
        st = x.get("step", {})
        rows.append([c,
                     " / ".join(fmt(_median(st[ax]["overshoot_pct"]) if ax in st else None, 3)
                                for ax in AXES),
                     " / ".join(fmt(_median(st[ax]["settling_time_s"]) if ax in st else None, 3)
                                for ax in AXES),
                     " / ".join(fmt(_median(x["rate_command_deg_s"][ax]["peak_accel_deg_s2"]))
                                for ax in AXES),
                     f"{x['limit_hits']['rate']} / {x['limit_hits']['accel']}"])
    return _table(header, rows)


def sweep_tables(results: Mapping[str, Any]) -> list[str]:
    """One table per sweep direction: the wind's axis' 3-sigma per controller and speed."""
    sw = results.get("wind_sweep")
    if not sw:
        return []
    out = []
    for d, cur in sw["curves"].items():
        header = [f"{d} wind, 3σ {cur['axis']} (mdeg)"] + [f"{v:g} km/h" for v in cur["speeds_kmh"]]
        rows = [[c] + [fmt(v) for v in cur["three_sigma_mdeg"][c]["median"]]
                for c in cur["three_sigma_mdeg"]]
        rows.append(["yardstick (analytic)"] + [fmt(v) for v in cur["yardstick_three_sigma_mdeg"]])
        out.append(_table(header, rows))
    return out


LEGEND = """\
## How to read it

* **3σ** is 3 × the standard deviation of the true servo error (command − encoder angle,
  unquantised) about its mean, in mdeg, after the scenario's warm-up (hold and track: 5 s);
  the report's Table 4 figure.  **rms** includes the mean, **max** is the largest magnitude.
  Every figure is the **median over the seeds**; every controller sees the same episodes
  (start, wind direction, gusts, trajectory) for the same seed.
* In 50 km/h **front** wind the wind acts on **elevation**, in **side** wind on **azimuth**:
  those axes are in bold; the other axis is nearly wind-free.
* **÷ yardstick**: 3σ divided by the analytic expected 3σ of the yardstick, the H2-optimal
  full-order LQG for the benchmark's own cost (`baselines/yardstick.py`), defined for
  scenarios with one fixed wind.  It is not a bound in simulation (the encoder is truly
  quantised): the yardstick run as a controller gets about 1.1–1.4× its own figure.
* **pointing 3σ el / xel**: the dish's true elevation / cross-elevation pointing error
  (structure outputs, including its deformation), shown for the hold scenarios only: the
  environment gives the dish's angles relative to the start, which in step, track and slew
  contain the commanded motion (they are in results.json all the same).
* **step** and **slew**: their 3σ and max are dominated by the commanded transient itself
  (a 0.1° step is 100 mdeg); read the step table and the command table instead.  **step**:
  0.1° command step on both axes at 1 s, no wind; overshoot (%) and settling time into the
  2 % band (s, from the step; ∞: not settled in the episode).  **slew**: 5° move on both axes
  in 30 km/h wind; peak rate and acceleration of the applied command and the limiter hits show
  who drives into the limits (0.25 °/s, 0.2 °/s²).  **track**: slow sinusoidal trajectory in
  a random 30–70 km/h wind and direction (no yardstick: the wind is not fixed).
* **wind sweep**: the hold scenario at each speed, shorter episodes (see its heading); the
  yardstick row is its analytic expected 3σ at that speed.
* **limit hits**: steps where the environment's limiter clipped the rate (or its change),
  summed over seeds.  **act()**: wall time of one control decision (median over seeds of the
  per-episode median and p95), noisy on a loaded machine.  **fallbacks**: MPC solves replaced
  by the LQG action; **failures**: controller exceptions (episode ended); **terminated**:
  episodes that hit the 1° error bound or the travel limits.
"""


def results_markdown(results: Mapping[str, Any]) -> str:
    """results.md: the main table, the detail tables, the sweep and the legend."""
    b, m = results["bench"], results["meta"]
    cfg = b["config"]
    steps = ", ".join(f"{s} {n}" for s, n in cfg["steps"].items())
    parts = ["# DSS-14 controller benchmark", "",
             f"Controllers: {', '.join(m['controllers'])}; seeds {m['seeds']}; episode steps "
             f"(50 Hz): {steps}; plant: {'randomised' if cfg['env_kwargs'] else 'nominal'}; "
             f"{'--quick; ' if cfg['quick'] else ''}wall time {b['wall_time_s']['total']:.0f} s.",
             ""]
    if b["notes"]:
        parts += [f"Note: {n}" for n in b["notes"]] + [""]
    parts += ["## 3σ servo error (mdeg), az / el", "", main_table(results), ""]
    st = step_table(results)
    if st:
        parts += ["## Step response (Fig. 21 scenario)", "", st, ""]
    sw = sweep_tables(results)
    if sw:
        s = results["wind_sweep"]
        parts += [f"## 3σ error vs wind speed (hold, {s['steps']} steps per episode, "
                  f"seeds {s['seeds']})", ""]
        for t in sw:
            parts += [t, ""]
    parts += ["## Errors in detail (mdeg, median over seeds)", "", error_table(results), "",
              "## Commands, limits, timing, health", "", command_table(results), "", LEGEND]
    return "\n".join(parts)


def write_results(results: Mapping[str, Any], out: str | Path) -> tuple[Path, Path]:
    """Write results.json and results.md into ``out`` (created).

    :return: their paths
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    pj, pm = out / "results.json", out / "results.md"
    pj.write_text(json.dumps(results, indent=1) + "\n")
    pm.write_text(results_markdown(results))
    return pj, pm


# ------------------------------------------------------------------------------ figures
def _colors(names: Sequence[str]) -> dict[str, Any]:
    import matplotlib.pyplot as plt
    cyc = plt.get_cmap("tab10")
    return {n: cyc(i % 10) for i, n in enumerate(names)}


def _log_y(axp: Any) -> None:
    """Log y axis with plain numbers (0.1, 0.2, ..., 1, 2) as tick labels."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axp.set_yscale("log")
    plain = FuncFormatter(lambda y, _: f"{y:g}")
    axp.yaxis.set_major_formatter(plain)
    lo, hi = axp.get_ylim()
    if hi / lo < 100:  # two decades or less: label the 2s and 5s too
        axp.yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
        axp.yaxis.set_minor_formatter(plain)
    else:
        axp.yaxis.set_minor_formatter(NullFormatter())


def _traces(ran: Mapping[str, Any], scenario: str, seed: int) -> dict[str, dict[str, np.ndarray]]:
    """Time histories of one scenario and seed, per controller."""
    return {ep["controller"]: ep["trace"] for ep in ran["main"]["episodes"]
            if ep["scenario"] == scenario and ep["seed"] == seed and "trace" in ep}


def plot_error_bars(results: Mapping[str, Any], path: Path) -> None:
    """Bar chart of the 3-sigma servo errors per controller and scenario, az and el, with the
    min-max over seeds and the yardstick's expected value where defined."""
    import matplotlib.pyplot as plt

    ctrls, scens = results["meta"]["controllers"], results["meta"]["scenarios"]
    col = _colors(ctrls)
    w = 0.8 / len(ctrls)
    fig, axes = plt.subplots(2, 1, figsize=(max(7.0, 1.6 * len(scens) + 2), 7), sharex=True)
    for i, (axp, ax) in enumerate(zip(axes, AXES)):
        for k, c in enumerate(ctrls):
            ts = [results["summary"][c][s]["servo_error_mdeg"][ax]["three_sigma"] for s in scens]
            med = np.array([t["median"] for t in ts])
            lo = np.clip(med - np.array([t["min"] for t in ts]), 0, None)
            hi = np.clip(np.array([t["max"] for t in ts]) - med, 0, None)
            x = np.arange(len(scens)) - 0.4 + (k + 0.5) * w
            axp.bar(x, med, w, color=col[c], label=c, yerr=[lo, hi], capsize=2,
                    error_kw={"lw": 0.7})
        first = True
        for j, s in enumerate(scens):
            ref = results["yardstick"].get(s)
            if ref is not None:
                axp.hlines(ref["three_sigma_mdeg"][i], j - 0.45, j + 0.45, colors="k",
                           linestyles="--", lw=1.2, label="yardstick (analytic)" if first else None)
                first = False
        _log_y(axp)
        axp.set_ylabel(f"3σ servo error {ax}, mdeg")
        axp.grid(True, axis="y", which="both", alpha=0.3)
    axes[0].legend(fontsize=8, ncol=min(3, len(ctrls) + 1))
    axes[-1].set_xticks(np.arange(len(scens)), scens)
    fig.suptitle(f"3σ servo error, median over seeds {results['meta']['seeds']} (bars: min–max)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_hold_histories(results: Mapping[str, Any], ran: Mapping[str, Any], path: Path) -> bool:
    """Servo-error time histories in the hold scenarios (first seed, every controller, az and
    el); False when no hold scenario ran."""
    import matplotlib.pyplot as plt

    scens = [s for s in ("hold_front", "hold_side") if s in results["meta"]["scenarios"]]
    if not scens:
        return False
    seed = results["meta"]["seeds"][0]
    ctrls = results["meta"]["controllers"]
    col = _colors(ctrls)
    fig, axes = plt.subplots(len(scens), 2, figsize=(11, 3.2 * len(scens)), squeeze=False)
    for r, s in enumerate(scens):
        tr = _traces(ran, s, seed)
        for i, ax in enumerate(AXES):
            axp = axes[r][i]
            # largest first, so that the small errors stay visible on top
            order = sorted(tr, key=lambda c: -float(np.std(tr[c]["servo_error_mdeg"][:, i])))
            for c in order:
                axp.plot(tr[c]["t"], tr[c]["servo_error_mdeg"][:, i], lw=0.6, color=col[c], label=c)
            axp.axvline(SCENARIOS[s].warmup_s, color="0.5", lw=0.8, ls=":")
            axp.set_title(f"{s}: {ax}", fontsize=10)
            axp.set_ylabel("servo error, mdeg")
            axp.grid(True, alpha=0.3)
        axes[r][0].legend(fontsize=7, loc="upper right")
    for axp in axes[-1]:
        axp.set_xlabel("time, s")
    fig.suptitle(f"Servo error (true), seed {seed}; dotted: end of warm-up")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def plot_step_responses(results: Mapping[str, Any], ran: Mapping[str, Any], path: Path) -> bool:
    """Encoder position vs time in the step scenario (first seed) with the command; False
    when the step scenario did not run."""
    import matplotlib.pyplot as plt

    if "step" not in results["meta"]["scenarios"]:
        return False
    seed = results["meta"]["seeds"][0]
    ctrls = results["meta"]["controllers"]
    col = _colors(ctrls)
    tr = _traces(ran, "step", seed)
    # widest first: controllers with the same response stay visible one over the other
    lw = {c: 2.6 - 1.6 * k / max(1, len(ctrls) - 1) for k, c in enumerate(ctrls)}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for i, (axp, ax) in enumerate(zip(axes, AXES)):
        cmd = None
        for c in ctrls:
            if c in tr:
                axp.plot(tr[c]["t"], tr[c]["encoder_deg"][:, i] * 1e3, lw=lw[c], color=col[c],
                         label=c)
                cmd = tr[c]
        if cmd is not None:
            axp.plot(cmd["t"], cmd["command_deg"][:, i] * 1e3, "k--", lw=1.0, label="command")
        axp.set_title(f"step, {ax}", fontsize=10)
        axp.set_xlabel("time, s")
        axp.set_ylabel("encoder position (from start), mdeg")
        axp.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"Step responses, seed {seed}")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def plot_wind_sweep(results: Mapping[str, Any], path: Path) -> bool:
    """3-sigma error vs wind speed per controller and the yardstick's expected curve (front
    wind: el, side wind: az); False without a sweep."""
    import matplotlib.pyplot as plt

    sw = results.get("wind_sweep")
    if not sw:
        return False
    curves = sw["curves"]
    col = _colors(results["meta"]["controllers"])
    fig, axes = plt.subplots(1, len(curves), figsize=(5.5 * len(curves), 4.2), squeeze=False)
    for axp, (d, cur) in zip(axes[0], curves.items()):
        v = np.asarray(cur["speeds_kmh"])
        for c, y in cur["three_sigma_mdeg"].items():
            axp.plot(v, y["median"], "o-", color=col[c], label=c, ms=4)
            if len(sw["seeds"]) > 1:
                axp.fill_between(v, y["min"], y["max"], color=col[c], alpha=0.15, lw=0)
        yard = np.array([np.nan if x is None else x for x in cur["yardstick_three_sigma_mdeg"]])
        axp.plot(v, yard, "k--s", ms=4, label="yardstick (analytic)")
        _log_y(axp)
        axp.set_xlabel("mean wind speed, km/h")
        axp.set_ylabel(f"3σ servo error {cur['axis']}, mdeg")
        axp.set_title(f"hold, {d} wind → {cur['axis']}", fontsize=10)
        axp.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"3σ vs wind speed ({sw['steps']} steps, median over seeds {sw['seeds']})")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def draw_figures(results: Mapping[str, Any], ran: Mapping[str, Any], out: str | Path) -> list[str]:
    """Draw the PNG figures that the run has data for (:data:`FIGURES`).

    :param results: :func:`assemble_results`'s output
    :param ran: :func:`run_plan`'s output (the time histories)
    :param out: output folder
    :return: the file names written
    """
    import matplotlib
    matplotlib.use("Agg")

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plot_error_bars(results, out / FIGURES[0])
    written = [FIGURES[0]]
    for name, ok in ((FIGURES[1], plot_hold_histories(results, ran, out / FIGURES[1])),
                     (FIGURES[2], plot_step_responses(results, ran, out / FIGURES[2])),
                     (FIGURES[3], plot_wind_sweep(results, out / FIGURES[3]))):
        if ok:
            written.append(name)
    return written


# ------------------------------------------------------------------------------ threads
class blas_threads:
    """Context manager: run with ``n`` OpenBLAS threads in numpy's and scipy's BLAS, restored
    on exit.

    The bench's matrices are small (at most 132 states); with two threads on two busy cores
    OpenBLAS spends its time waiting (the yardstick's design took 4 s instead of 0.1 s when
    another job shared the machine), and one thread makes the controllers' timings steadier.
    Uses threadpoolctl (numpy and scipy each bundle an OpenBLAS; both are limited);
    ``n`` None: unchanged.

    :param n: threads, default 1
    """

    def __init__(self, n: int | None = 1) -> None:
        self.n = n
        self.n_libraries = 0
        self._limiter: Any = None

    def __enter__(self) -> "blas_threads":
        if self.n is None:
            return self
        import numpy  # noqa: F401  (load both BLAS libraries first)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        blas = ThreadpoolController().select(user_api="blas")
        self.n_libraries = len(blas.lib_controllers)
        self._limiter = blas.limit(limits=int(self.n))
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._limiter is not None:
            self._limiter.restore_original_limits()
            self._limiter = None


# ------------------------------------------------------------------------------ all of it
def bench(plan: BenchPlan, progress: bool = True, threads: int | None = 1) -> dict[str, Any]:
    """Run a plan and write its outputs into ``plan.out``.

    :param plan: the plan (:func:`build_plan`)
    :param progress: show the progress bar
    :param threads: OpenBLAS threads while running (:class:`blas_threads`), default 1; None
        leaves them alone
    :return: ``results`` (results.json's content), ``main_table`` (Markdown), ``markdown``
        (results.md), ``files`` (paths written), ``figures`` (names), ``wall_time_s``, and
        ``ran`` (:func:`run_plan`'s output, with the time histories)
    """
    t0 = time.perf_counter()
    with blas_threads(threads) as bt:
        ran = run_plan(plan, progress=progress)
    results = assemble_results(plan, ran, time.perf_counter() - t0)
    results["bench"]["blas_threads"] = {"threads": threads, "libraries_set": bt.n_libraries}
    figures = draw_figures(results, ran, plan.out) if plan.figures else []
    wall = time.perf_counter() - t0
    results["bench"]["wall_time_s"]["total"] = wall
    results["bench"]["figures"] = figures
    pj, pm = write_results(results, plan.out)
    return {"results": results, "main_table": main_table(results),
            "markdown": results_markdown(results), "files": [pj, pm] + [plan.out / f for f in figures],
            "figures": figures, "wall_time_s": wall, "ran": ran}


__all__ = ["BenchOptionError", "BenchPlan", "DEFAULT_CONTROLLERS", "DEFAULT_SCENARIOS",
           "DEFAULT_SEEDS", "DEFAULT_WIND_SPEEDS_KMH", "FIGURES", "assemble_results", "bench",
           "build_plan", "draw_figures", "main_table", "package_versions", "parse_seeds",
           "parse_wind_speeds", "ppo_factory", "results_markdown", "run_plan", "write_results"]
