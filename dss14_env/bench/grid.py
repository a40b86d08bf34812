"""The wind direction and speed grid: the hold scenario at every wind direction from the front
(0°) through the side (90°) to the back (180°) in 45° steps at 50 km/h, and in light (10 km/h)
and strong (70 km/h) wind from the front and the side, each controller scored on the dish's
pointing error through the bench's one runner (:func:`dss14_env.bench.runner.run`).

Run it with ``python scripts/direction_grid.py`` (``--ppo-model PATH`` adds a trained policy's
column); its results are ``docs/results/direction_grid.json`` and the table
``docs/results/direction_grid.md``.  Per grid point and controller: the pooled 3σ of the
pointing error on both beam axes (el and xel) with its 95 % interval, and its ratio to the
reference controller (the report's PI) on the same seeds with the paired 95 % interval
(:mod:`dss14_env.bench.statistics`).

>>> [name for name, _, _ in grid_points()][:3]
['hold_0deg_50kmh', 'hold_45deg_50kmh', 'hold_90deg_50kmh']
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from dss14_env.bench import catalog, runner
from dss14_env.bench.catalog import ControllerRow, Scenario
from dss14_env.bench.plan import SWEEP_WARMUP_S, control_period
from dss14_env.bench.report import fmt_ci, fmt_ratio, package_versions
from dss14_env.core.results import POINTING, POINTING_AXES, ratio_cell

#: wind directions of the 50 km/h row, degrees from the front (0: front, 90: side, 180: back)
DIRECTIONS_DEG: tuple[float, ...] = (0.0, 45.0, 90.0, 135.0, 180.0)
#: the grid's main wind speed, km/h
SPEED_KMH = 50.0
#: light and strong wind, km/h, each at :data:`SPEED_DIRECTIONS_DEG`
OTHER_SPEEDS_KMH: tuple[float, ...] = (10.0, 70.0)
#: the directions of the light and strong wind: front and side
SPEED_DIRECTIONS_DEG: tuple[float, ...] = (0.0, 90.0)
#: the controllers of the committed grid: the report's PI, the pointing LQG, the pointing LQG
#: scheduled on the measured wind speed and the monopulse LQG
CONTROLLERS: tuple[str, ...] = ("pi_kp1", "lqg_pointing", "lqg_pointing_sched", "lqg_monopulse")
#: episodes per grid point (seeds 0, 1, ...) and their length, s
EPISODES = 64
SECONDS = 30.0
#: the preset every grid point runs, with its wind replaced
BASE_SCENARIO = "hold_front"


def point_name(direction_deg: float, speed_kmh: float) -> str:
    """A grid point's name, e.g. ``hold_135deg_50kmh``."""
    return f"hold_{direction_deg:g}deg_{speed_kmh:g}kmh"


def grid_points() -> list[tuple[str, float, float]]:
    """(name, direction in degrees, speed in km/h) of every grid point, in table order."""
    pts = [(point_name(d, SPEED_KMH), d, SPEED_KMH) for d in DIRECTIONS_DEG]
    pts += [(point_name(d, v), d, v) for v in OTHER_SPEEDS_KMH for d in SPEED_DIRECTIONS_DEG]
    return pts


def grid_scenario(direction_deg: float, speed_kmh: float, seconds: float) -> Scenario:
    """The hold scenario with a fixed wind of ``speed_kmh`` from ``direction_deg``, ``seconds``
    long, the hold's warm-up left out.
    """
    base = catalog.SCENARIOS[BASE_SCENARIO].scenario()
    dt = control_period(base.env)
    env = {**base.env, "wind_speed_kmh": float(speed_kmh), "wind_direction": math.radians(direction_deg)}
    return Scenario(env, round(seconds / dt), SWEEP_WARMUP_S,
                    f"hold, {speed_kmh:g} km/h wind from {direction_deg:g}°")


def check_options(seeds: int, seconds: float) -> None:
    """Bad episode counts or lengths raise ValueError naming the option, before any work."""
    if not isinstance(seeds, int) or seeds < 2:
        raise ValueError(f"--episodes: at least 2 (an interval needs two episodes), got {seeds!r}")
    if not seconds > SWEEP_WARMUP_S + 1.0:
        raise ValueError(f"--seconds: longer than the {SWEEP_WARMUP_S:g}-s warm-up plus 1 s, got {seconds!r}")


def grid_controllers(names: Sequence[str] | None = None, ppo_model: str | None = None
                     ) -> list[str | ControllerRow]:
    """The grid's controllers: ``names`` (default :data:`CONTROLLERS`), plus the trained policy
    at ``ppo_model`` under its own name.

    :raises ValueError: an unknown name, or a policy that cannot act on the environment or is
        named like a catalog controller (one line naming the option)
    """
    chosen: list[str | ControllerRow] = list(CONTROLLERS if names is None else names)
    for n in chosen:
        if n not in catalog.CONTROLLERS:
            raise ValueError(f"--controllers: unknown controller {n!r}; known: "
                             f"{', '.join(catalog.CONTROLLERS)}")
    if ppo_model is not None:
        problem = catalog.policy_name_problem(ppo_model)
        row = catalog.policy_row(ppo_model)
        problem = problem or row.policy_problem()
        if problem is not None:
            raise ValueError(f"--ppo-model: {problem}")
        chosen.append(row)
    return chosen


def run_grid(controllers: Sequence[str | ControllerRow] = CONTROLLERS, episodes: int = EPISODES,
             seconds: float = SECONDS, progress: Callable[[str, int], None] | None = None,
             command: str = "") -> dict[str, Any]:
    """Every controller at every grid point on seeds ``0 .. episodes - 1``.

    :param controllers: catalog names or rows (a trained policy's:
        :func:`dss14_env.bench.catalog.policy_row`); the reference is ``pi_kp1`` when it runs
    :param episodes: episodes per grid point
    :param seconds: episode length, s
    :param progress: the runner's progress callback
    :param command: the command line, for the record
    :return: ``{"grid": {"command", "directions_deg", "speed_kmh", ...}, "versions", "meta",
        "points": {name: {"direction_deg", "speed_kmh"}}, "summary": {controller: {point:
        {"pointing_error_mdeg": {el, xel: 3σ cell}, "vs_reference_pointing_error_mdeg": ...}}}}``
    """
    check_options(episodes, seconds)
    pts = grid_points()
    scens = [(n, grid_scenario(d, v, seconds)) for n, d, v in pts]
    t0, c0 = time.perf_counter(), time.process_time()
    res = runner.run(list(controllers), scens, range(episodes), progress=progress)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    key = "vs_reference_pointing_error_mdeg"
    summary = {c: {s: {POINTING: {ax: cell[POINTING][ax]["three_sigma"] for ax in POINTING_AXES},
                       **({key: cell[key]} if key in cell else {})}
                   for s, cell in cells.items()} for c, cells in res["summary"].items()}
    return {"grid": {"command": command, "directions_deg": list(DIRECTIONS_DEG), "speed_kmh": SPEED_KMH,
                     "other_speeds_kmh": list(OTHER_SPEEDS_KMH),
                     "other_speed_directions_deg": list(SPEED_DIRECTIONS_DEG), "episodes": episodes,
                     "seconds": seconds, "warmup_s": SWEEP_WARMUP_S, "wall_time_s": wall,
                     "cpu_time_s": cpu},
            "versions": package_versions(),
            "meta": {k: res["meta"][k] for k in ("controllers", "scenarios", "seeds", "sequential_seeds",
                                                   "batched", "reference", "statistics")},
            "points": {n: {"direction_deg": d, "speed_kmh": v} for n, d, v in pts},
            "summary": summary}


def grid_table(results: Mapping[str, Any]) -> str:
    """The grid as Markdown: one row per grid point and controller, the pointing 3σ el and xel
    (mdeg, ± 95 % half-width) and their ratios to the reference on the same seeds [paired 95 %
    CI], then a one-line legend.
    """
    ref = results["meta"].get("reference")
    head = ["wind", "controller", "pointing 3σ el (mdeg)", "pointing 3σ xel (mdeg)"]
    head += [f"el ÷ {ref}", f"xel ÷ {ref}"] if ref else []
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, p in results["points"].items():
        wind = f"{p['speed_kmh']:g} km/h from {p['direction_deg']:g}°"
        for c in results["meta"]["controllers"]:
            cell = results["summary"].get(c, {}).get(name)
            row = [wind, c] + [fmt_ci(cell[POINTING][ax]) if cell else "—" for ax in POINTING_AXES]
            if ref:
                row += ["1" if c == ref and cell else
                        fmt_ratio(ratio_cell(cell, "vs_reference", ax, POINTING)) for ax in POINTING_AXES]
            lines.append("| " + " | ".join(row) + " |")
    g = results["grid"]
    legend = (f"Hold scenario, {g['seconds']:g}-s episodes ({g['warmup_s']:g}-s warm-up left out), seeds "
              f"0–{g['episodes'] - 1} at every point; wind direction from the front (0°: front, 90°: "
              f"side, 180°: back).  3σ of the dish's true pointing error, value ± 95 % CI half-width "
              f"(bootstrap over episodes)"
              + (f"; ÷ {ref}: the ratio to it on the same seeds [paired 95 % CI], n.s.: the interval "
                 "contains 1" if ref else "")
              + f".  Wall time {g['wall_time_s']:.0f} s.")
    return "\n".join(lines) + "\n\n" + legend + "\n"


__all__ = ["BASE_SCENARIO", "CONTROLLERS", "DIRECTIONS_DEG", "EPISODES", "OTHER_SPEEDS_KMH", "SECONDS",
           "SPEED_DIRECTIONS_DEG", "SPEED_KMH", "check_options", "grid_controllers", "grid_points",
           "grid_scenario", "grid_table", "point_name", "run_grid"]
