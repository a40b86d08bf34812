"""The bench's PNG figures, drawn on :class:`matplotlib.figure.Figure` with the Agg canvas (no
pyplot, no global state) and written atomically.

* ``errors_3sigma.png``: 3σ servo error per controller and scenario as bars with their 95 %
  confidence intervals as whiskers, azimuth and elevation; the wind scenarios (hold, track)
  and the commanded moves (step, slew; two orders of magnitude larger) on separate axes; log
  scales with labelled minor ticks; the yardstick's analytic 3σ as a dashed line;
* ``hold_time_histories.png``: the servo error of every controller in the hold scenarios
  (first seed);
* ``step_responses.png``: encoder position in the step scenario (first seed), every
  controller in its own colour, line style and marker, with a zoom on the overshoot;
* ``wind_sweep.png``: 3σ of the wind's axis vs mean wind speed with 95 % confidence bands and
  the yardstick's analytic curve.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.bench import catalog
from dss14_env.bench.plan import LOADED_AXES
from dss14_env.core.outdir import atomic_save_figure
from dss14_env.core.results import Cell
from dss14_env.core.units import AXES

#: the figures :func:`draw_figures` can write
FIGURES = ("errors_3sigma.png", "hold_time_histories.png", "step_responses.png", "wind_sweep.png")
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f")
_LINES = ("-", "--", "-.", ":", (0, (6, 2, 1, 2, 1, 2)), (0, (1, 1)))
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
DPI = 100


def styles(names: Sequence[str]) -> dict[str, dict[str, Any]]:
    """A distinct colour, line style and marker per controller (in the given order)."""
    return {n: {"color": _COLORS[i % len(_COLORS)], "ls": _LINES[i % len(_LINES)],
                "marker": _MARKERS[i % len(_MARKERS)]} for i, n in enumerate(names)}


def _figure(width: float, height: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Any, path: Path) -> None:
    atomic_save_figure(fig, path, dpi=DPI)


def log_axis(axp: Any, which: str = "y") -> None:
    """A log axis whose major (1, 10, ...) and minor (2, 5 ×) ticks carry plain numbers."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    axis = axp.yaxis if which == "y" else axp.xaxis
    (axp.set_yscale if which == "y" else axp.set_xscale)("log")
    axis.set_major_locator(LogLocator(base=10.0))
    axis.set_major_formatter(plain)
    axis.set_minor_locator(LogLocator(base=10.0, subs=(2.0, 5.0)))
    axis.set_minor_formatter(plain)
    axp.tick_params(axis=which, which="minor", labelsize=7)


def _ci(cell: Mapping[str, Any] | None) -> tuple[float, float, float]:
    if cell is None:
        return np.nan, np.nan, np.nan
    c = Cell.from_dict(cell)
    return c.value, c.ci95[0], c.ci95[1]


def scenario_group(name: str) -> str | None:
    """The group of errors_3sigma.png a scenario is drawn in (its row's, :data:`catalog.GROUPS`),
    None for a name the catalog does not hold.
    """
    row = catalog.SCENARIOS.get(name)
    return None if row is None else row.group


def plot_error_bars(results: Mapping[str, Any], path: Path) -> bool:
    """3σ bars with 95 % CI whiskers (see the module docstring); False when nothing ran."""
    ctrls, scens = results["meta"]["controllers"], results["meta"]["scenarios"]
    groups = [g for g in ([s for s in scens if scenario_group(s) == group] for group in catalog.GROUPS) if g]
    if not groups:
        return False
    st = styles(ctrls)
    fig = _figure(max(7.0, 1.9 * len(scens) + 2.5), 7.0)
    grid = fig.add_gridspec(2, len(groups), width_ratios=[len(g) for g in groups])
    w = 0.8 / len(ctrls)
    for col, group in enumerate(groups):
        for row, ax in enumerate(AXES):
            axp = fig.add_subplot(grid[row, col])
            shown = []
            for k, c in enumerate(ctrls):
                v, lo, hi = np.array([_ci((results["summary"][c].get(s) or {}).get("servo_error_mdeg", {})
                                          .get(ax, {}).get("three_sigma")) for s in group]).T
                x = np.arange(len(group)) - 0.4 + (k + 0.5) * w
                axp.bar(x, v, w, color=st[c]["color"], label=c)
                ok = ~(np.isnan(lo) | np.isnan(hi))
                axp.errorbar(x[ok], v[ok], yerr=[np.clip(v - lo, 0, None)[ok], np.clip(hi - v, 0, None)[ok]],
                             fmt="none", ecolor="k", elinewidth=1.0, capsize=3)
                shown += [y for y in np.concatenate([v, lo[ok]]) if np.isfinite(y) and y > 0]
            first = True
            for j, s in enumerate(group):
                ref = results["yardstick"].get(s)
                if ref is not None:
                    axp.hlines(ref["three_sigma_mdeg"][row], j - 0.45, j + 0.45, colors="k",
                               linestyles="--", lw=1.3, label="yardstick (analytic)" if first else None)
                    shown.append(float(ref["three_sigma_mdeg"][row]))
                    first = False
            log_axis(axp)
            if shown:
                axp.set_ylim(0.6 * min(shown), 1.6 * max(shown))
            axp.set_xticks(np.arange(len(group)),
                           [f"{s}\n({'/'.join(LOADED_AXES[s])} loaded)" if s in LOADED_AXES else s
                            for s in group])
            axp.set_ylabel(f"3σ servo error {ax}, mdeg")
            axp.grid(True, axis="y", which="both", alpha=0.3)
            axp.set_title(("wind: " if scenario_group(group[0]) == "wind" else "commanded moves: ") + ax,
                          fontsize=10)
            if row == 0 and col == 0:
                handles, labels = axp.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(6, len(labels)), fontsize=9)
    fig.suptitle("3σ servo error pooled over episodes; whiskers: 95 % confidence intervals", fontsize=11)
    _save(fig, path)
    return True


def _traces(ran: Mapping[str, Any], scenario: str) -> dict[str, dict[str, np.ndarray]]:
    """Time histories of one scenario's first seed, per controller."""
    return {ep["controller"]: ep["trace"] for ep in ran["main"]["episodes"]
            if ep["scenario"] == scenario and "trace" in ep}


def plot_hold_histories(results: Mapping[str, Any], ran: Mapping[str, Any], path: Path) -> bool:
    """Servo-error time histories in the hold scenarios (first seed, every controller, az and
    el); False when no hold scenario ran.
    """
    scens = [s for s in ("hold_front", "hold_side") if s in results["meta"]["scenarios"]]
    if not scens:
        return False
    ctrls = results["meta"]["controllers"]
    st = styles(ctrls)
    fig = _figure(12.0, 3.3 * len(scens) + 0.8)
    axes = fig.subplots(len(scens), 2, squeeze=False)
    warm = results["meta"]["warmup_s"]
    count = encoder_count_mdeg()
    for r, s in enumerate(scens):
        tr = _traces(ran, s)
        for i, ax in enumerate(AXES):
            axp = axes[r][i]
            # largest first, so that the small errors stay visible on top; each controller's
            # line style and markers (staggered), so that equal traces stay apart
            order = sorted(tr, key=lambda c: -float(np.std(tr[c]["servo_error_mdeg"][:, i])))
            for c in order:
                n = len(tr[c]["t"])
                every = max(n // 10, 1)
                axp.plot(tr[c]["t"], tr[c]["servo_error_mdeg"][:, i], lw=0.8, color=st[c]["color"],
                         ls=st[c]["ls"], marker=st[c]["marker"], ms=4,
                         markevery=(ctrls.index(c) * every // max(len(ctrls), 1), every), label=c)
            if count is not None:
                for sign in (1, -1):
                    axp.axhline(sign * count, color="k", lw=0.9, ls=(0, (5, 3)), zorder=5)
            axp.axvline(warm.get(s, 0.0), color="0.4", lw=0.8, ls=":")
            loaded = " (loaded)" if ax in LOADED_AXES.get(s, ()) else ""
            axp.set_title(f"{s}: {ax}{loaded}", fontsize=10)
            axp.set_ylabel("servo error, mdeg")
            axp.grid(True, alpha=0.3)
    for axp in axes[-1]:
        axp.set_xlabel("time, s")
    handles = [_line(st[c], c) for c in ctrls if any(c in _traces(ran, s) for s in scens)]
    if count is not None:
        handles.append(_line({"color": "k", "ls": (0, (5, 3)), "marker": None},
                             f"±1 encoder count ({count:.3f} mdeg)", marker=False))
    fig.legend(handles=handles, loc="outside right center", fontsize=10, title="controller")
    seed = results["meta"]["seeds"]
    seed0 = (seed.get(scens[0]) if isinstance(seed, Mapping) else seed)[0]
    fig.suptitle(f"True servo error, seed {seed0}; dotted: end of the warm-up; dashed black: one "
                 f"encoder count, below which a figure is at the encoder's resolution", fontsize=11)
    _save(fig, path)
    return True


def encoder_count_mdeg() -> float | None:
    """One count of the shipped environment's encoder (``encoder_bits`` per turn), mdeg; None
    without quantisation.
    """
    from dss14_env.envs.config import load_env_config

    bits = load_env_config().encoder_bits
    return None if bits is None else 360e3 / 2 ** bits


def _line(style: Mapping[str, Any], label: str, marker: bool = True) -> Any:
    from matplotlib.lines import Line2D

    return Line2D([], [], color=style["color"], ls=style["ls"], lw=2.0,
                  marker=style["marker"] if marker else None, label=label)


def _step_axis(axes: Any, i: int, ctrls: Sequence[str], tr: Mapping[str, Any],
               st: Mapping[str, Mapping[str, Any]]) -> None:
    """One axis of the step figure: every controller (full and zoomed) and the command."""
    ax = AXES[i]
    cmd = None
    for k, c in enumerate(c for c in ctrls if c in tr):
        t, y = tr[c]["t"], tr[c]["encoder_deg"][:, i] * 1e3
        every = max(1, len(t) // 12)
        for axp in axes[:, i]:
            axp.plot(t, y, color=st[c]["color"], ls=st[c]["ls"], lw=1.6, marker=st[c]["marker"],
                     ms=5, markevery=(k * every // max(1, len(ctrls)), every), label=c)
        cmd = tr[c]
    if cmd is not None:
        for axp in axes[:, i]:
            axp.plot(cmd["t"], cmd["command_deg"][:, i] * 1e3, color="k", lw=0.9, ls=(0, (2, 2)),
                     label="command")
        final = float(np.max(np.abs(cmd["command_deg"][:, i]))) * 1e3
        if final > 0:
            axes[1, i].set_ylim(0.9 * final, 1.4 * final)
            axes[1, i].axhspan(0.98 * final, 1.02 * final, color="0.85", zorder=0)
    axes[0, i].set_title(f"step, {ax}", fontsize=10)
    axes[1, i].set_title(f"step, {ax}: overshoot and settling into the 2 % band (grey)", fontsize=10)
    for axp in axes[:, i]:
        axp.set_ylabel("encoder position from start, mdeg")
        axp.grid(True, alpha=0.3)
    axes[1, i].set_xlabel("time, s")


def plot_step_responses(results: Mapping[str, Any], ran: Mapping[str, Any], path: Path) -> bool:
    """Encoder position vs time in the step scenario (first seed) with the command: full
    response above, the overshoot zoomed below, every controller in its own colour, line
    style and marker (markers staggered, so that equal responses stay visible); False when the
    step scenario did not run.
    """
    if "step" not in results["meta"]["scenarios"]:
        return False
    ctrls = results["meta"]["controllers"]
    st = styles(ctrls)
    tr = _traces(ran, "step")
    if not tr:
        return False
    fig = _figure(12.0, 7.5)
    axes = fig.subplots(2, 2)
    for i in range(len(AXES)):
        _step_axis(axes, i, ctrls, tr, st)
    from matplotlib.lines import Line2D

    handles = [_line(st[c], c) for c in ctrls if c in tr]
    handles.append(Line2D([], [], color="k", lw=0.9, ls=(0, (2, 2)), label="command"))
    fig.legend(handles=handles, loc="outside right center", fontsize=10, title="controller")
    seed = results["meta"]["seeds"]
    seed0 = (seed.get("step") if isinstance(seed, Mapping) else seed)[0]
    fig.suptitle(f"Step responses, seed {seed0}", fontsize=11)
    _save(fig, path)
    return True


def plot_wind_sweep(results: Mapping[str, Any], path: Path) -> bool:
    """3σ of the wind's axis vs mean wind speed per controller with 95 % confidence bands and
    the yardstick's analytic curve (front wind: el, side wind: az); False without a sweep.
    """
    sw = results.get("wind_sweep")
    if not sw:
        return False
    curves = sw["curves"]
    st = styles(results["meta"]["controllers"])
    fig = _figure(5.8 * len(curves) + 1.8, 4.8)
    axes = fig.subplots(1, len(curves), squeeze=False)[0]
    for axp, (d, cur) in zip(axes, curves.items(), strict=True):
        v = np.asarray(cur["speeds_kmh"], float)
        for c, cells in cur["three_sigma_mdeg"].items():
            val, lo, hi = np.array([_ci(x) for x in cells]).T
            if np.all(np.isnan(val)):
                continue
            axp.plot(v, val, color=st[c]["color"], ls=st[c]["ls"], marker=st[c]["marker"], ms=5, lw=1.5,
                     label=c)
            ok = ~(np.isnan(lo) | np.isnan(hi))
            if np.count_nonzero(ok) > 1:
                axp.fill_between(v[ok], lo[ok], hi[ok], color=st[c]["color"], alpha=0.2, lw=0)
            elif np.any(ok):
                axp.errorbar(v[ok], val[ok], yerr=[val[ok] - lo[ok], hi[ok] - val[ok]], fmt="none",
                             ecolor=st[c]["color"], capsize=3)
        yard = np.array([np.nan if x is None else x for x in cur["yardstick_three_sigma_mdeg"]], float)
        axp.plot(v, yard, "k--", lw=1.3, label="yardstick (analytic)")
        log_axis(axp)
        axp.set_xlabel("mean wind speed, km/h")
        axp.set_ylabel(f"3σ servo error {cur['axis']}, mdeg")
        axp.set_title(f"hold, {d} wind → {cur['axis']}", fontsize=10)
        axp.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right center", fontsize=9)
    fig.suptitle(f"3σ vs wind speed ({sw['seconds']:g}-s episodes; bands: 95 % confidence intervals)",
                 fontsize=11)
    _save(fig, path)
    return True


def draw_figures(results: Mapping[str, Any], ran: Mapping[str, Any], out: str | Path) -> list[str]:
    """Draw the PNG figures that the run has data for (:data:`FIGURES`).

    :param results: :func:`dss14_env.bench.report.assemble_results`'s output
    :param ran: :func:`dss14_env.bench.run.run_plan`'s output (the time histories)
    :param out: output folder (existing)
    :return: the file names written
    """
    out = Path(out)
    written = []
    for name, ok in ((FIGURES[0], lambda p: plot_error_bars(results, p)),
                     (FIGURES[1], lambda p: plot_hold_histories(results, ran, p)),
                     (FIGURES[2], lambda p: plot_step_responses(results, ran, p)),
                     (FIGURES[3], lambda p: plot_wind_sweep(results, p))):
        if ok(out / name):
            written.append(name)
    return written


__all__ = ["FIGURES", "draw_figures", "scenario_group", "log_axis", "plot_error_bars", "plot_hold_histories",
           "plot_step_responses", "plot_wind_sweep", "styles"]
