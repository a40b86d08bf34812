"""results.json, results.md and the tables of a bench run.

:func:`assemble_results` turns :func:`dss14_env.bench.run.run_plan`'s output into results.json's
content; :func:`results_markdown` renders results.md from it (and nothing else), so the tables
can be regenerated from a results file at any time (``scripts/readme_tables.py`` renders the
README's compact headline (:func:`headline_table`) and docs/results/bench_default.md from the
committed default results).  Every figure is shown with its 95 %
confidence interval as ``value ± half-width`` (:func:`fmt_ci`), ratios as ``value [low,
high]`` with ``n.s.`` where the interval contains 1.

results.json keeps every episode's metrics (``episodes[controller][scenario][metric] = [one
value per episode]``, or ``{"same": value}`` when every episode has the same value;
:func:`episode_columns`; 6 significant digits), so every interval can be recomputed
(:func:`episode_rows` turns them back into the runner's episode dicts).
"""

from __future__ import annotations

import json
import math
import os
import platform
from collections.abc import Callable, Iterator, Mapping, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.bench import catalog
from dss14_env.bench.envelope import band_envelopes, envelope_table
from dss14_env.bench.plan import LOADED_AXES, SWEEP_DIRECTIONS, SWEEP_WARMUP_S, BenchPlan
from dss14_env.bench.statistics import flatten
from dss14_env.core.outdir import atomic_write_text
from dss14_env.core.results import (
    ERRORS,
    POINTING,
    POINTING_AXES,
    POINTING_AXIS_OF,
    SERVO,
    Cell,
    RatioCell,
    ratio_cell,
    ratio_key,
    summary_cell,
)
from dss14_env.core.units import AXES

#: distributions whose versions go into results.json
VERSIONED = ("numpy", "scipy", "gymnasium", "stable-baselines3", "torch", "cvxpy", "dss14-env")
#: the files of a run besides the figures
RESULT_FILES = ("results.json", "results.md")
#: significant digits of the per-episode values in results.json
EPISODE_DIGITS = 6


# ------------------------------------------------------------------------------ results.json
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


def load_average() -> list[float] | None:
    """The machine's 1, 5 and 15 minute load averages (None where the OS has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


#: per-episode entries stored as one column per leaf (``servo_error_mdeg.az.three_sigma``);
#: any other entry is one column of its own (e.g. ``fallback_log``, a list per episode)
_NESTED = ("servo_error_mdeg", "pointing_error_mdeg", "rate_command_deg_s", "limit_hits",
           "controller_time_ms", "step", "smoothness")


def _flat(ep: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in ep.items():
        if k in _NESTED and isinstance(v, Mapping):
            out.update(flatten(v, f"{k}."))
        else:
            out[k] = v
    return out


def _round(x: Any) -> Any:
    if isinstance(x, float) and math.isfinite(x) and x != 0.0:
        return float(f"{x:.{EPISODE_DIGITS}g}")
    return x


#: per-episode entries not stored per episode (the same for every episode: in the config)
_SKIP = ("controller", "scenario", "limits")


def episode_columns(episodes: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, dict[str, list]]]:
    """The runner's episode dicts as ``{controller: {scenario: {metric path: [values]}}}``
    (nested metrics flattened to dotted paths, e.g. ``servo_error_mdeg.el.three_sigma``).
    """
    out: dict[str, dict[str, dict[str, list]]] = {}
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for ep in episodes:
        groups.setdefault((ep["controller"], ep["scenario"]), []).append(ep)
    for (c, s), eps in groups.items():
        flats = [_flat({k: v for k, v in ep.items() if k not in _SKIP and k != "trace"}) for ep in eps]
        keys: list[str] = []
        for f in flats:
            keys += [k for k in f if k not in keys]
        cols: dict[str, Any] = {}
        for k in keys:
            vals = [_round(f.get(k)) for f in flats]
            same = k != "seed" and len(vals) > 1 and all(json.dumps(v) == json.dumps(vals[0]) for v in vals)
            cols[k] = {"same": vals[0]} if same else vals
        out.setdefault(c, {})[s] = cols
    return out


def episode_rows(columns: Mapping[str, Mapping[str, Mapping[str, list]]]) -> list[dict[str, Any]]:
    """:func:`episode_columns` back into the runner's episode dicts (with ``controller`` and
    ``scenario``).
    """
    rows: list[dict[str, Any]] = []
    for c, scens in columns.items():
        for s, cols in scens.items():
            n = len(cols["seed"])
            for i in range(n):
                ep: dict[str, Any] = {"controller": c, "scenario": s}
                for path, vals in cols.items():
                    v = vals["same"] if isinstance(vals, dict) else vals[i]
                    if v is None and path.startswith("step."):
                        continue
                    d = ep
                    *head, last = path.split(".")
                    for h in head:
                        d = d.setdefault(h, {})
                    d[last] = v
                rows.append(ep)
    return rows


def wind_sweep_curves(plan: BenchPlan, ran: Mapping[str, Any]) -> dict[str, Any]:
    """The sweep per direction: the wind's axis' pooled 3σ cell (value, interval, episodes)
    per controller and speed (None where the controller did not run), and the yardstick's
    analytic expected 3σ.
    """
    main, sweep = ran["main"], ran["sweep"]
    curves: dict[str, Any] = {}
    for d in plan.sweep_directions:
        axis = SWEEP_DIRECTIONS[d][1]
        i = AXES.index(axis)
        yard: list[float | None] = []
        ctrl: dict[str, list[Any]] = {c: [] for c in plan.controllers}
        for name, dd, _, same in ran["sweep_points"]:
            if dd != d:
                continue
            src, key = (main, same) if same is not None else (sweep, name)
            ref = src["yardstick"].get(key)
            yard.append(None if ref is None else float(ref["three_sigma_mdeg"][i]))
            for c in plan.controllers:
                cell = src["summary"].get(c, {}).get(key)
                ctrl[c].append(None if cell is None else cell["servo_error_mdeg"][axis]["three_sigma"])
        curves[d] = {"axis": axis, "speeds_kmh": list(plan.wind_speeds_kmh),
                     "yardstick_three_sigma_mdeg": yard, "three_sigma_mdeg": ctrl}
    return curves


def assemble_results(plan: BenchPlan, ran: Mapping[str, Any], wall_time_s: float) -> dict[str, Any]:
    """results.json's content (no time histories).

    :param plan: the plan
    :param ran: :func:`dss14_env.bench.run.run_plan`'s result
    :param wall_time_s: the whole bench's wall time so far, s
    """
    main = ran["main"]
    sweep: dict[str, Any] | None = None
    if plan.sweep_directions:
        s = ran["sweep"]
        sweep = {"speeds_kmh": list(plan.wind_speeds_kmh), "directions": list(plan.sweep_directions),
                 "steps": plan.sweep.steps, "seconds": plan.sweep.steps * plan.dt,
                 "warmup_s": SWEEP_WARMUP_S, "seeds": list(plan.sweep.seeds),
                 "sequential_seeds": list(plan.sweep.sequential_seeds),
                 "points": {n: {"direction": d, "speed_kmh": v, "same_as": same}
                            for n, d, v, same in ran["sweep_points"]},
                 "curves": wind_sweep_curves(plan, ran),
                 "summary": s["summary"] if s else {}, "yardstick": s["yardstick"] if s else {},
                 "episodes": episode_columns(s["episodes"]) if s else {}}
    meta = {k: v for k, v in main["meta"].items() if k != "statistics"}
    var = ran.get("variants")
    variants: dict[str, Any] | None = None
    if var is not None:
        variants = {"variants": list(plan.variants), "scenarios": list(plan.variant_scenarios),
                    "steps": plan.variant_run.steps, "seconds": plan.variant_run.steps * plan.dt,
                    "seeds": list(plan.variant_run.seeds),
                    "points": {n: {"scenario": sc, "variant": v} for n, sc, v in ran["variant_points"]},
                    "meta": {k: v for k, v in var["meta"].items() if k != "statistics"},
                    "summary": var["summary"], "yardstick": var["yardstick"],
                    "episodes": episode_columns(var["episodes"])}
    envelopes = None
    if plan.sweep_directions:
        points = [(same or n, d, v) for n, d, v, same in ran["sweep_points"]]
        episodes = list(main["episodes"]) + (list(ran["sweep"]["episodes"]) if ran["sweep"] else [])
        envelopes = band_envelopes(episodes, points, seed=plan.bootstrap_seed)
    return {
        "bench": {"command": plan.command, "config": plan.as_dict(), "notes": list(plan.notes),
                  "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                  "wall_time_s": {**ran["wall_time_s"], "total": wall_time_s},
                  "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(),
                              "load_average_start": ran.get("load_average_start"),
                              "load_average_end": load_average()}},
        "versions": package_versions(),
        "statistics": main["meta"].get("statistics"),
        "meta": meta,
        "summary": main["summary"],
        "yardstick": main["yardstick"],
        "wind_sweep": sweep,
        "drive_variants": variants,
        "wind_envelope": envelopes,
        "episodes": episode_columns(main["episodes"]),
    }


def _is_leafy(x: Any) -> bool:
    """A dict or list with no dict or list inside but short lists of numbers: one line."""
    vals = x.values() if isinstance(x, dict) else x
    return all(not isinstance(v, (dict, list)) or (isinstance(v, list) and len(v) <= 4 and
                                                   all(not isinstance(u, (dict, list)) for u in v))
               for v in vals)


def _dumps(x: Any, indent: str = "") -> str:
    """JSON with one line per innermost dict (e.g. a figure with its interval) or per
    controller x scenario of per-episode columns.
    """
    if isinstance(x, dict) and x and not _is_leafy(x) and not _is_columns(x):
        inner = indent + " "
        items = ",\n".join(f"{inner}{json.dumps(str(k))}: {_dumps(v, inner)}" for k, v in x.items())
        return "{\n" + items + "\n" + indent + "}"
    if isinstance(x, list) and x and any(isinstance(v, (dict, list)) for v in x) and not _is_leafy(x):
        inner = indent + " "
        return "[\n" + ",\n".join(inner + _dumps(v, inner) for v in x) + "\n" + indent + "]"
    compact = isinstance(x, dict) and _is_columns(x)
    return json.dumps(x, separators=(",", ":") if compact else (", ", ": "))


def _is_columns(x: dict) -> bool:
    """Per-episode columns of one controller and scenario (they have a ``seed`` list)."""
    return isinstance(x.get("seed"), list)


def results_json(results: Mapping[str, Any]) -> str:
    """results.json's text: indented down to one line per figure (value, interval, episodes)
    and one line per controller and scenario of per-episode columns.
    """
    return _dumps(dict(results)) + "\n"


# ------------------------------------------------------------------------------ numbers
def fmt(x: Any, digits: int = 3) -> str:
    """A number for the tables: ``—`` for None/NaN, ``∞``, integers as they are, else
    ``digits`` significant figures (no exponent; numbers below 0.01 with 4 decimals).
    """
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


def _decimals(hw: float) -> int:
    """Decimals that show a half-width with 1 significant digit (2 when it starts with 1)."""
    e = math.floor(math.log10(hw))
    lead = hw / 10 ** e
    return max(0, -e + (1 if lead < 1.95 else 0))


def fmt_ci(cell: Mapping[str, Any] | Cell | None, digits: int = 3) -> str:
    """``value ± half-width`` of an estimate ``{"value", "ci95", "n_episodes"}``, rounded to
    the half-width's first significant digit (``2.80 ± 0.06``); a value without an interval
    (one episode) is shown as ``0.50 (1 ep.)``.
    """
    if cell is None:
        return "—"
    c = cell if isinstance(cell, Cell) else Cell.from_dict(cell)
    v, (lo, hi) = c.value, c.ci95
    if math.isnan(v):
        return "—"
    if math.isinf(v):
        return fmt(v)
    if math.isnan(lo) or math.isnan(hi) or math.isinf(lo) or math.isinf(hi):
        n = c.n_episodes
        return f"{fmt(v, digits)} ({n} ep.)" if n == 1 else f"{fmt(v, digits)} (no CI)"
    hw = c.half_width
    if hw <= 0:
        return f"{fmt(v, digits)} ± 0"
    d = _decimals(hw)
    if v != 0:  # at most 5 significant digits of the value
        d = min(d, max(0, 4 - math.floor(math.log10(abs(v)))))
    return f"{v:.{d}f} ± {hw:.{d}f}"


def fmt_ratio(r: Mapping[str, Any] | RatioCell | None) -> str:
    """A ratio with its interval, ``0.19 [0.18, 0.20]``, and ``n.s.`` when the interval
    contains 1.
    """
    if r is None:
        return "—"
    c = r if isinstance(r, RatioCell) else RatioCell.from_dict(r)
    v, (lo, hi) = c.value, c.ci95
    if math.isnan(v):
        return "—"
    if math.isnan(lo) or math.isnan(hi):
        return f"{fmt(v, 2)} (no CI)"
    hw = 0.5 * (hi - lo)
    d = _decimals(hw) if hw > 0 else 2
    d = max(d, 2) if abs(v) < 10 else d
    txt = f"{v:.{d}f} [{lo:.{d}f}, {hi:.{d}f}]"
    return txt + (" n.s." if c.significant is False else "")


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _bold(text: str, yes: bool) -> str:
    return f"**{text}**" if yes and text != "—" else text


def _cell(results: Mapping[str, Any], c: str, s: str) -> Mapping[str, Any] | None:
    return results["summary"].get(c, {}).get(s)


def _cells(results: Mapping[str, Any]) -> Iterator[tuple[str, str, Mapping[str, Any]]]:
    """Every (controller, scenario, summary) that the results hold, in table order."""
    for c in results["meta"]["controllers"]:
        for s in results["meta"]["scenarios"]:
            x = _cell(results, c, s)
            if x is not None:
                yield c, s, x


# ------------------------------------------------------------------------------ tables
def scenario_group(results: Mapping[str, Any], scenario: str) -> str:
    """The scenario's group (:data:`dss14_env.bench.catalog.GROUPS`): the run's record, else
    the catalog's row (a drive variant's: its hold scenario's), else ``"wind"``.
    """
    g = (results["meta"].get("groups") or {}).get(scenario)
    if g is None:
        row = catalog.SCENARIOS.get(scenario.partition("@")[0])
        g = row.group if row is not None else "wind"
    return str(g)


def scored_by_3sigma(results: Mapping[str, Any]) -> list[str]:
    """The run's scenarios scored by their 3σ (the wind group), in table order."""
    return [s for s in results["meta"]["scenarios"] if scenario_group(results, s) != "move"]


def move_scenarios(results: Mapping[str, Any]) -> list[str]:
    """The run's commanded-move scenarios (the move group), scored by the move's response."""
    return [s for s in results["meta"]["scenarios"] if scenario_group(results, s) == "move"]


def loaded_axes(scenario: str, quantity: str = SERVO) -> tuple[str, ...]:
    """The axes of ``quantity`` the scenario's wind loads (bold in the tables): the drive
    axes of the catalog, or the pointing axes they move the beam on (azimuth: cross-elevation).
    """
    axes = LOADED_AXES.get(scenario.partition("@")[0], ())  # a drive variant's: its hold scenario's
    return axes if quantity == SERVO else tuple(POINTING_AXIS_OF[ax] for ax in axes)


def _episode_counts(results: Mapping[str, Any], c: str) -> str:
    scens = results["meta"]["scenarios"]
    counts = sorted({_cell(results, c, s)["n_episodes"] for s in scens if _cell(results, c, s)})
    if len(counts) > 1:
        return "–".join(str(n) for n in (counts[0], counts[-1]))
    return str(counts[0]) if counts else "0"


def three_sigma_table(results: Mapping[str, Any], quantity: str = SERVO) -> str:
    """3σ of ``quantity`` per controller and wind scenario (:func:`scored_by_3sigma`; the
    commanded moves are in :func:`move_table`), both axes (servo error: az / el; pointing
    error: el / xel), ``value ± 95 % half-width`` (the wind's axis in bold), with the episodes
    behind each row, and, for the servo error, the yardstick's analytic expected value.
    """
    ctrls, scens = results["meta"]["controllers"], scored_by_3sigma(results)
    axes = ERRORS[quantity]
    header = ["controller"] + [f"{s} {' / '.join(axes)}" for s in scens] + ["episodes per scenario"]
    rows = []
    for c in ctrls:
        r = [c]
        for s in scens:
            x = _cell(results, c, s)
            cells = [summary_cell(x, quantity, ax) for ax in axes]
            r.append("—" if x is None or None in cells else
                     " / ".join(_bold(fmt_ci(cl), ax in loaded_axes(s, quantity))
                                for cl, ax in zip(cells, axes, strict=True)))
        rows.append(r + [_episode_counts(results, c)])
    yard = _yardstick_figures(results, quantity)
    if yard:
        r = [f"{'pointing ' if quantity == POINTING else ''}yardstick (analytic)"]
        for s in scens:
            r.append(" / ".join(_bold(fmt(x), ax in loaded_axes(s, quantity))
                                for x, ax in zip(yard[s], axes, strict=True)) if s in yard else "—")
        rows.append(r + ["exact"])
    return _table(header, rows)


def _yardstick_figures(results: Mapping[str, Any], quantity: str) -> dict[str, list[float]]:
    """Per scenario with one fixed wind, the yardstick's analytic 3σ of ``quantity`` per axis
    (the servo error: the encoder yardstick's; the pointing error: the pointing yardstick's,
    where the results hold it).
    """
    out = {}
    for s, y in (results.get("yardstick") or {}).items():
        if quantity == SERVO:
            out[s] = list(y["three_sigma_mdeg"])
        elif isinstance(y.get("pointing"), Mapping) and "pointing_three_sigma_mdeg" in y["pointing"]:
            out[s] = list(y["pointing"]["pointing_three_sigma_mdeg"])
    return out


def main_table(results: Mapping[str, Any]) -> str:
    """3σ servo error at the drive encoders az / el per controller and scenario (the report's
    Table 4 quantity; :func:`three_sigma_table`).
    """
    return three_sigma_table(results, SERVO)


def pointing_table(results: Mapping[str, Any]) -> str:
    """3σ of the dish's true pointing error el / xel per controller and scenario, the
    headline (:func:`three_sigma_table`).
    """
    return three_sigma_table(results, POINTING)


def pointing_ratio_table(results: Mapping[str, Any]) -> str | None:
    """The pointing error's 3σ over the reference controller's (paired, same seeds), el / xel,
    for every controller and wind scenario; None when the reference did not run or the results
    hold no pointing ratios.
    """
    ref = results["meta"].get("reference")
    scens = scored_by_3sigma(results)
    key = ratio_key("vs_reference", POINTING)
    if not ref or not any(key in x for _, _, x in _cells(results)):
        return None
    yard = [(s, ax) for s in scens if s in _yardstick_figures(results, POINTING)
            for ax in loaded_axes(s, POINTING)]
    header = ["controller"] + [f"{s} el / xel ÷ {ref}" for s in scens]
    header += [f"{s} {ax} ÷ pointing yardstick" for s, ax in yard]
    rows = []
    for c in results["meta"]["controllers"]:
        r = [c]
        for s in scens:
            x = _cell(results, c, s)
            if c == ref and x is not None:
                r.append("1 / 1")
                continue
            rs = [ratio_cell(x, "vs_reference", ax, POINTING) for ax in POINTING_AXES]
            r.append("—" if x is None or None in rs else " / ".join(fmt_ratio(v) for v in rs))
        r += [fmt_ratio(ratio_cell(_cell(results, c, s), "vs_yardstick", ax, POINTING)) for s, ax in yard]
        rows.append(r)
    return _table(header, rows)


def ratio_table(results: Mapping[str, Any]) -> str | None:
    """The loaded axis of the hold scenarios (and the track's axes) over the reference
    controller (paired, same seeds) and over the yardstick's analytic figure.
    """
    scens = results["meta"]["scenarios"]
    ref = results["meta"].get("reference")
    cols = [(s, ax) for s in scens for ax in LOADED_AXES.get(s, ())]
    if not cols:
        return None
    header = ["controller"]
    if ref:
        header += [f"{s} {ax} ÷ {ref}" for s, ax in cols]
    header += [f"{s} {ax} ÷ yardstick" for s, ax in cols if s in results["yardstick"]]
    if len(header) == 1:
        return None
    rows = []
    for c in results["meta"]["controllers"]:
        r = [c]
        if ref:
            r += [fmt_ratio((_cell(results, c, s) or {}).get("vs_reference", {}).get(ax)) if c != ref else "1"
                  for s, ax in cols]
        r += [fmt_ratio((_cell(results, c, s) or {}).get("vs_yardstick", {}).get(ax))
              for s, ax in cols if s in results["yardstick"]]
        rows.append(r)
    return _table(header, rows)


def precision_table(results: Mapping[str, Any]) -> str | None:
    """The loaded axis' 3σ in the hold scenarios: value, 95 % interval, its half-width in %
    of the value, episodes and seconds of data.
    """
    cols = [(s, ax) for s in results["meta"]["scenarios"] for ax in LOADED_AXES.get(s, ())]
    if not cols:
        return None
    header = ["controller"] + [f"{s} {ax}: 3σ [95 % CI], half-width, episodes × s" for s, ax in cols]
    rows = []
    for c in results["meta"]["controllers"]:
        r = [c]
        for s, ax in cols:
            x = _cell(results, c, s)
            if x is None:
                r.append("—")
                continue
            t = x["servo_error_mdeg"][ax]["three_sigma"]
            lo, hi = t["ci95"]
            if lo is None or hi is None or math.isnan(lo):
                r.append(f"{fmt(t['value'])}, no CI, {t['n_episodes']} ep.")
                continue
            hw = 50.0 * (hi - lo) / t["value"]
            per = t["seconds"] / max(1, t["n_episodes"])
            r.append(f"{fmt(t['value'])} [{fmt(lo)}, {fmt(hi)}], ±{hw:.1f} %, "
                     f"{t['n_episodes']} × {per:g} s")
        rows.append(r)
    return _table(header, rows)


#: the columns of a move table: (header, where in the cell's ``step``, the axes, the statistic)
MOVE_COLUMNS: tuple[tuple[str, str | None, tuple[str, ...], str], ...] = (
    ("overshoot az / el (%)", None, AXES, "overshoot_pct"),
    ("2 % settling az / el (s)", None, AXES, "settling_time_s"),
    ("peak servo error az / el (mdeg)", None, AXES, "peak_error_mdeg"),
    ("servo rms after settling az / el (mdeg)", None, AXES, "settled_rms_mdeg"),
    ("peak pointing error el / xel (mdeg)", "pointing", POINTING_AXES, "peak_error_mdeg"),
    ("pointing rms after settling el / xel (mdeg)", "pointing", POINTING_AXES, "settled_rms_mdeg"))


def move_table(results: Mapping[str, Any], scenario: str) -> str | None:
    """The response to a commanded move per controller (:func:`dss14_env.baselines.rollout.
    move_response`): overshoot, 2 % settling time, peak error and rms after settling of the
    servo error (az / el) and of the pointing error (el / xel), with their intervals, then
    the peak command acceleration and the limiter hits; None when the scenario did not run.
    """
    if scenario not in results["meta"]["scenarios"]:
        return None
    header = ["controller"] + [h for h, *_ in MOVE_COLUMNS] + ["peak accel az / el (°/s²)",
                                                               "limit hits rate / accel (total)"]
    rows = []
    for c in results["meta"]["controllers"]:
        x = _cell(results, c, scenario)
        if x is None:
            rows.append([c] + ["—"] * (len(header) - 1))
            continue
        st = x.get("step", {})
        r = [c]
        for _, where, axes, stat in MOVE_COLUMNS:
            d = st.get(where, {}) if where else st
            r.append(" / ".join(fmt_ci(d[ax][stat]) if stat in d.get(ax, {}) else "—" for ax in axes))
        rows.append(r + [" / ".join(fmt_ci(x["rate_command_deg_s"][ax]["peak_accel_deg_s2"]) for ax in AXES),
                         f"{x['limit_hits']['rate']} / {x['limit_hits']['accel']}"])
    return _table(header, rows)


def smoothness_tables(results: Mapping[str, Any]) -> list[str]:
    """The command's smoothness per controller and scenario (:mod:`dss14_env.core.smoothness`):
    acceleration-limit hits in % of the periods, then the share of the command change's
    variance above 5 Hz (%), az / el; empty when the results hold neither.
    """
    ctrls, scens = results["meta"]["controllers"], results["meta"]["scenarios"]
    if not any("smoothness" in x for _, _, x in _cells(results)):
        return []

    def table(first: str, cell: Callable[[Mapping[str, Any]], str]) -> str:
        rows = []
        for c in ctrls:
            r = [c]
            for s in scens:
                sm = (_cell(results, c, s) or {}).get("smoothness")
                r.append("—" if sm is None else cell(sm))
            rows.append(r)
        return _table([first] + list(scens), rows)

    return [table("accel-limit hits (% of steps)", lambda sm: fmt_ci(sm["accel_limit_hits_pct"])),
            table("command change above 5 Hz az / el (%)",
                  lambda sm: " / ".join(fmt_ci(sm["command_change_hf_pct"][ax]) for ax in AXES))]


def sweep_tables(results: Mapping[str, Any]) -> list[str]:
    """One table per sweep direction: the wind's axis' 3σ per controller and speed."""
    sw = results.get("wind_sweep")
    if not sw:
        return []
    out = []
    for d, cur in sw["curves"].items():
        header = [f"{d} wind, 3σ {cur['axis']} (mdeg)"] + [f"{v:g} km/h" for v in cur["speeds_kmh"]]
        rows = [[c] + [fmt_ci(v) for v in cells] for c, cells in cur["three_sigma_mdeg"].items()
                if any(v is not None for v in cells)]
        rows.append(["yardstick (analytic)"] + [fmt(v) for v in cur["yardstick_three_sigma_mdeg"]])
        out.append(_table(header, rows))
    return out


def variant_tables(results: Mapping[str, Any]) -> list[str]:
    """The pointing error on the nominal model and the drive variants: the 3σ table of the hold
    scenarios (nominal columns from the main run, its controllers those that ran on the
    variants), then the ratios to the reference on the same seeds; empty when no variant ran.
    """
    dv = results.get("drive_variants")
    if not dv:
        return []
    ctrls = list(dv["meta"]["controllers"])
    names = [s for s in dv["scenarios"] if s in results["summary"].get(ctrls[0], {})]
    merged = {"meta": {"controllers": ctrls, "scenarios": names + list(dv["meta"]["scenarios"]),
                       "reference": dv["meta"].get("reference")},
              "summary": {c: {**{s: x for s, x in results["summary"].get(c, {}).items() if s in names},
                              **dv["summary"].get(c, {})} for c in ctrls},
              "yardstick": {**{s: y for s, y in results.get("yardstick", {}).items() if s in names},
                            **dv.get("yardstick", {})}}
    out = [pointing_table(merged)]
    pr = pointing_ratio_table(merged)
    if pr:
        out.append(pr)
    return out


def error_table(results: Mapping[str, Any]) -> str:
    """Detail: servo errors (3σ, rms, peak) and the dish's true pointing error per controller
    and scenario.
    """
    header = ["controller", "scenario", "3σ az", "3σ el", "rms az", "rms el", "peak az", "peak el",
              "pointing 3σ el", "pointing 3σ xel", "pointing peak el", "pointing peak xel"]
    rows = []
    for c, s, x in _cells(results):
        se, pe = x["servo_error_mdeg"], x["pointing_error_mdeg"]
        rows.append([c, s] + [fmt_ci(se[ax][st]) for st in ("three_sigma", "rms", "max") for ax in AXES]
                    + [fmt_ci(pe[ax][st]) for st in ("three_sigma", "max") for ax in ("el", "xel")])
    return _table(header, rows)


def command_table(results: Mapping[str, Any]) -> str:
    """Detail: commands, limiter hits, decision time and health per controller and scenario."""
    header = ["controller", "scenario", "peak rate az / el (°/s)", "limit hits per episode rate / accel",
              "decision time median / p95 (ms)", "run", "fallbacks", "failures", "terminated"]
    rows = []
    for c, s, x in _cells(results):
        rc, lh = x["rate_command_deg_s"], x["limit_hits"]["per_episode"]
        batched = results["meta"].get("batched", {}).get(c)
        rows.append([c, s,
                     " / ".join(fmt_ci(rc[ax]["peak"]) for ax in AXES),
                     f"{fmt_ci(lh['rate'])} / {fmt_ci(lh['accel'])}",
                     " / ".join(fmt(x["controller_time_ms"][k]["value"], 2) for k in ("median", "p95")),
                     "batched" if batched else "one at a time",
                     str(x["fallbacks"]), str(x["failures"]), str(x["terminated"])])
    return _table(header, rows)


def fallback_lines(results: Mapping[str, Any]) -> list[str]:
    """One line per episode with solver fallbacks: controller, scenario, seed and statuses."""
    out = []
    for c, scens in results.get("episodes", {}).items():
        for s, cols in scens.items():
            def col(key: str, i: int, cols: Mapping[str, Any] = cols) -> Any:
                v = cols.get(key)
                return v["same"] if isinstance(v, dict) else (None if v is None else v[i])
            for i in range(len(cols["seed"])):
                n = col("fallbacks", i)
                if not n:
                    continue
                log, st = col("fallback_log", i), col("fallback_statuses", i)
                if log:
                    detail = ", ".join(f"step {f['step']}: {f['status']}" for f in log[:10])
                    detail += ", ..." if len(log) > 10 else ""
                elif st:
                    detail = ", ".join(f"{k} × {v}" for k, v in st.items())
                else:
                    detail = "statuses not given"
                out.append(f"* {c}, {s}, seed {cols['seed'][i]}: {n} fallbacks ({detail})")
    return out


LEGEND = """\
## How to read it

* Every figure is **pooled over episodes** and shown as **value ± half-width of its 95 %
  confidence interval** (percentile bootstrap over episodes: the episodes are independent,
  each with its own seed; results.json has the interval's ends, the episodes and the seconds
  of data behind it, and every episode's values).  Two figures whose intervals overlap may
  not differ.
* **pointing** (the headline) is the dish's true pointing error: the command minus the
  structure's pointing angle, elevation and cross-elevation, from the model's pointing outputs,
  deformation included -- where the beam points, which is what the Ka-band (2 mdeg) and X-band
  (8 mdeg) requirements are about.  **3σ** is 3 × its standard deviation about each episode's
  mean, pooled over the episodes as a root mean square, after the warm-up (hold, track, sweep:
  5 s).
* **servo error** is the true servo error at the drive encoders (command − axis angle,
  unquantised), the same statistics: the report's Table 4 quantity and the model's
  calibration anchor.  A controller can hold the encoders still while the structure above
  them swings, so the two can rank controllers differently.  **rms** includes the mean;
  **peak** is each episode's largest |error|, averaged over the episodes.
* In **front** wind the wind loads **elevation** (pointing: el), in **side** wind **azimuth**
  (pointing: xel): those axes are in bold.
* **÷ reference** (the report's PI, kp 1): the ratio of pooled 3σ (pointing or servo) on the seeds both
  controllers ran, with a paired bootstrap interval (the same gusts in numerator and
  denominator, so the ratio is much sharper than either figure).  **÷ yardstick**: over the
  analytic expected 3σ of the H2-optimal full-order LQG for the scenario's wind
  (`baselines/yardstick.py`), optimal for the benchmark's quadratic cost on the model with white
  quantisation noise (a bound on that cost, not on the 3σ: more action change gives a smaller
  3σ); the interval is the controller's.  **n.s.**: not significant, the
  interval contains 1.
* Controllers that act on batches (PI, LQG, PPO with the batch interface) run many episodes
  at once through the vector environment; the MPC runs one episode at a time on the first
  seeds of the same list, so its intervals are wider (see the episodes column).  The same
  seed is the same episode (start, wind direction, gusts, trajectory) for every controller.
* **commanded moves** (**step**: 0.1° command step on both axes at 1 s, no wind; **slew**: 5°
  on both axes in 30 km/h wind) are scored by their response, not by a 3σ (which would measure
  the move itself): overshoot past the target (% of the move), settling into the 2 % band
  (s from the move's end; ∞: not settled; median over episodes), the peak |error| and the
  rms error after settling, of the servo error (az / el) and of the pointing error (el /
  xel).  **track**: slow
  sinusoidal track in a random 30–70 km/h wind and direction (wide intervals by design).
* **smoothness**: **accel-limit hits (%)** is the share of an episode's steps in which the
  limiter clipped the change of the rate command; **command change above 5 Hz (%)** is, per
  axis, the share of the variance of the rate command's first difference above 5 Hz (Welch
  power spectral density; white noise gives 80 % at the 50-Hz control rate, a slow command
  about 0); both over the whole episode, means over the episodes.
* **limit hits**: steps where the environment's limiter clipped the rate or its change
  (0.25 °/s, 0.2 °/s²).  **decision time**: wall time of one control decision (a batched
  controller's batch call divided by its rows), median over episodes.  **fallbacks**: MPC
  solves replaced by the fallback law (each episode's solver statuses are listed below and in
  results.json); **failures**: controller exceptions (the episode ends); **terminated**:
  episodes that hit the 1° error bound or the travel limits.
"""


def _timing(b: Mapping[str, Any]) -> str:
    """``Wall time 120 s (CPU 110 s) on 2 cores, load average 1.2 at the start``."""
    cpu = b.get("cpu_time_s")
    load = b["machine"].get("load_average_start")
    return (f"Wall time {b['wall_time_s']['total']:.0f} s"
            + (f" (CPU {cpu:.0f} s)" if cpu is not None else "")
            + f" on {b['machine']['cpu_count']} cores"
            + (f", load average {load[0]:.1f} at the start" if load else ""))


def results_markdown(results: Mapping[str, Any]) -> str:
    """results.md: the main table, ratios, precision, details, the sweep and the legend."""
    b, m = results["bench"], results["meta"]
    cfg = b["config"]
    runs = "; ".join(f"{s} {r['seconds']:g} s × {len(r['seeds'])} (one at a time: "
                     f"{len(r['sequential_seeds'])})" for s, r in cfg["runs"].items())
    parts = ["# DSS-14 controller benchmark", "",
             f"Controllers: {', '.join(m['controllers'])}. Episodes per scenario: {runs}. "
             f"Plant: {'randomised' if cfg['env_kwargs'] else 'nominal'}. "
             f"{'--quick. ' if cfg['quick'] else ''}{_timing(b)}.", ""]
    if b["notes"]:
        parts += [f"Note: {n}" for n in b["notes"]] + [""]
    parts += ["## The dish's true pointing error: 3σ (mdeg), el / xel, 95 % confidence intervals "
              "(the commanded moves: their own tables below)", "",
              pointing_table(results), ""]
    pr = pointing_ratio_table(results)
    if pr:
        parts += ["## Pointing error ÷ the reference, el / xel, 95 % confidence intervals", "", pr, ""]
    parts += ["## 3σ servo error at the drive encoders (mdeg), az / el, 95 % confidence intervals "
              "(the report's Table 4 quantity)", "", main_table(results), ""]
    for title, t in (("## Ratios of the loaded axis' 3σ servo error, 95 % confidence intervals",
                      ratio_table(results)),
                     ("## Precision of the hold figures", precision_table(results))):
        if t:
            parts += [title, "", t, ""]
    for s in move_scenarios(results):
        t = move_table(results, s)
        if t:
            parts += [f"## Commanded move: {s}, 95 % confidence intervals", "", t, ""]
    sm = smoothness_tables(results)
    if sm:
        parts += ["## Command smoothness: acceleration-limit hits and the command change's variance "
                  "above 5 Hz, 95 % confidence intervals (dss14_env/core/smoothness.py)", ""]
        for t in sm:
            parts += [t, ""]
    sw = sweep_tables(results)
    if sw:
        s = results["wind_sweep"]
        parts += [f"## 3σ error vs wind speed (hold, {s['seconds']:g}-s episodes, {len(s['seeds'])} "
                  f"per point; the 50 km/h points are the hold scenarios)", ""]
        for t in sw:
            parts += [t, ""]
    vt = variant_tables(results)
    if vt:
        dv = results["drive_variants"]
        parts += [f"## The drive/structure split: pointing error on the nominal model and the drive "
                  f"variants ({', '.join(dv['variants'])}; `name@variant`; {dv['seconds']:g}-s episodes, "
                  f"{len(dv['seeds'])} per scenario on a variant; controllers designed on the nominal "
                  f"model; the pointing yardstick is each model's own)", ""]
        for t in vt:
            parts += [t, ""]
    env = results.get("wind_envelope")
    if env and env["controllers"]:
        req = env["requirements_rms_mdeg"]
        parts += [f"## Wind envelope: the highest mean wind (km/h) up to which the rms pointing error "
                  f"stays within the Ka-band requirement ({req['Ka']:.2f} mdeg per axis, el and xel) and "
                  f"the X-band one ({req['X']:.2f}), 95 % intervals (the sweep's speeds and directions; "
                  f"dss14_env/bench/envelope.py)", "", envelope_table(env), ""]
    parts += ["## Errors in detail (mdeg)", "", error_table(results), "",
              "## Commands, limits, timing, health", "", command_table(results), ""]
    fl = fallback_lines(results)
    if fl:
        parts += ["### Solver fallbacks per episode", ""] + fl + [""]
    parts += [LEGEND]
    return "\n".join(parts)


#: the scenarios of the compact headline table (:func:`headline_table`)
HEADLINE_SCENARIOS = ("hold_front", "hold_side")
#: the full tables of a run: where :func:`headline_table` points to
FULL_TABLES = RESULT_FILES[1]


def headline_table(results: Mapping[str, Any], full_tables: str = FULL_TABLES) -> str:
    """The compact headline: per controller, the 3σ of the dish's true pointing error on the
    axis the wind loads in each hold (hold_front: el, hold_side: xel) with its ratio to the
    reference controller on the same seeds (paired 95 % CI), then a one-line legend naming
    ``full_tables``, where the full tables are.  Holds the results lack are left out.
    """
    ref = results["meta"].get("reference")
    cols = [(s, ax) for s in HEADLINE_SCENARIOS if s in results["meta"]["scenarios"]
            for ax in loaded_axes(s, POINTING)]
    header = ["controller"]
    for s, ax in cols:
        header += [f"{s} {ax} 3σ (mdeg)"] + ([f"÷ {ref}"] if ref else [])
    rows = []
    for c in results["meta"]["controllers"]:
        r = [c]
        for s, ax in cols:
            x = _cell(results, c, s)
            r.append(fmt_ci(summary_cell(x, POINTING, ax)))
            if ref:
                r.append("1" if c == ref and x is not None else
                         fmt_ratio(ratio_cell(x, "vs_reference", ax, POINTING)))
        rows.append(r)
    legend = ("3σ of the dish's true pointing error on the axis the wind loads, value ± 95 % CI "
              "half-width (bootstrap over episodes)"
              + (f"; ÷ {ref}: the ratio to it on the same seeds [paired 95 % CI], below 1 is "
                 "better, n.s.: the interval contains 1" if ref else "")
              + f"; full tables: {full_tables}.")
    return _table(header, rows) + "\n\n" + legend + "\n"


#: the entries of a run's results that time it (wall clock and CPU, per run, controller and
#: episode), which differ from run to run; an episode's column is named by its first part
#: (``controller_time_ms.median``)
TIMING_KEYS = frozenset({"controller_time_ms", "controller_wall_time_s", "wall_time_s", "cpu_time_s"})
#: the sections of results.json that describe the run (command, machine, versions), not its figures
RUN_SECTIONS = ("bench", "versions")


def without_timings(x: Any) -> Any:
    """``x`` (results.json's content or a part of it) without its :data:`TIMING_KEYS` entries."""
    if isinstance(x, Mapping):
        return {k: without_timings(v) for k, v in x.items() if str(k).split(".")[0] not in TIMING_KEYS}
    if isinstance(x, list):
        return [without_timings(v) for v in x]
    return x


def run_figures(results: Mapping[str, Any]) -> dict[str, Any]:
    """What a bench run found: its results without the run's description
    (:data:`RUN_SECTIONS`) and timings (:func:`without_timings`); two runs of one plan on the
    same machine give equal figures, whatever their ``--jobs`` and the processes' caches.
    """
    return without_timings({k: v for k, v in results.items() if k not in RUN_SECTIONS})


def write_results(results: Mapping[str, Any], out: str | Path) -> tuple[Path, Path]:
    """Write results.json and results.md into ``out`` (an existing folder), atomically.

    :return: their paths
    """
    out = Path(out)
    pj, pm = out / RESULT_FILES[0], out / RESULT_FILES[1]
    atomic_write_text(pj, results_json(results))
    atomic_write_text(pm, results_markdown(results))
    return pj, pm


__all__ = ["LEGEND", "RESULT_FILES", "assemble_results", "command_table", "episode_columns",
           "episode_rows", "error_table", "fmt", "fmt_ci", "fmt_ratio", "headline_table", "loaded_axes",
           "main_table",
           "package_versions", "pointing_ratio_table", "pointing_table",
           "three_sigma_table",
           "precision_table", "ratio_table", "results_json", "results_markdown", "RUN_SECTIONS",
           "run_figures", "smoothness_tables", "sweep_tables", "TIMING_KEYS", "wind_sweep_curves",
           "without_timings", "write_results"]
