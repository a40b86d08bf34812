"""Statistics, tables and figures of a robustness campaign (:mod:`dss14_env.bench.campaign`).

Per controller and wind condition, over the campaign's plants (one episode per plant):

* **the episode's 3σ pointing error** (the headline): the larger of the elevation and
  cross-elevation 3σ of the dish's true pointing error after the warm-up (command minus the
  structure's pointing angle, deformation included), and **its 3σ servo error**: the larger of
  the azimuth and elevation 3σ of the true servo error at the drive encoders (the report's
  Table 4 quantity) (:func:`episode_three_sigma`), for the episodes that ran to the end
  (neither terminated nor failed; those are counted apart);
* their **median**, **95th percentile** and **worst** (maximum), each with a 95 % percentile
  bootstrap interval over plants (:func:`dss14_env.core.stats.bootstrap_ci`, 2000 resamples,
  a generator seeded by the cell's position, so the intervals are reproducible).  The
  bootstrap interval of the worst case cannot reach above the observed worst: it shows how much
  the worst case rests on a few plants, not how bad an unseen plant can be;
* the **share of episodes that meet a pointing requirement** (3σ pointing error at most the
  requirement on both axes, and the episode ran to the end; by default 2 mdeg for Ka-band and
  8 mdeg for X-band, :data:`DEFAULT_REQUIREMENTS`) with its Wilson score interval (scipy's
  ``binomtest(...).proportion_ci(method="wilson")``: unlike the bootstrap, not degenerate when
  every plant meets it);
* **terminated** and **failed** episodes, **fallbacks** of the MPC to its LQG action (total,
  and episodes with at least one), limiter hits.

>>> check_requirements({"Ka": 2, "X": 8})
{'Ka': 2.0, 'X': 8.0}
>>> share_ci(9, 10)["ci95"][0] < 0.9 < share_ci(9, 10)["ci95"][1]
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dss14_env.bench import catalog
from dss14_env.bench.campaign_spec import CampaignSpec
from dss14_env.bench.plan import control_period
from dss14_env.bench.report import fmt, package_versions
from dss14_env.core.outdir import atomic_save_figure
from dss14_env.core.results import ERRORS, POINTING, SERVO, episode_error
from dss14_env.core.stats import bootstrap_ci
from dss14_env.core.text import counted

#: pointing requirements by default: 3σ pointing error, mdeg.  The half-power beamwidth of a 70-m
#: dish, about 1.2 lambda / D, is 9.2 mdeg at Ka-band (32 GHz) and 35 mdeg at X-band (8.4 GHz);
#: each requirement is about a fifth of it, where a Gaussian beam's pointing loss,
#: 12 (theta / theta_hp)^2 dB, is about 0.6 dB at the 3σ excursion
DEFAULT_REQUIREMENTS = {"Ka": 2.0, "X": 8.0}
#: the key of each quantity's 3σ distribution in a summary cell
THREE_SIGMA_KEYS = {POINTING: "pointing_three_sigma_mdeg", SERVO: "three_sigma_mdeg"}
#: the quantity the requirements' shares are of
REQUIREMENT_QUANTITY = POINTING
#: fewest completed episodes a cell's 3σ distribution is estimated from (with one, its median
#: and 95th percentile would be that episode's figure with an interval of zero width): fewer
#: are reported as not estimable (—)
MIN_UNITS = 2
#: the statistics of the 3σ distribution and how each is computed from a sample
QUANTILES = {"median": lambda x: float(np.median(x)), "p95": lambda x: float(np.percentile(x, 95)),
             "worst": lambda x: float(np.max(x))}


def check_requirements(reqs: Mapping[str, float] | None) -> dict[str, float]:
    """Requirements as ``{name: mdeg}``, each a finite number > 0 (default
    :data:`DEFAULT_REQUIREMENTS`).

    :raises ValueError: ``--requirements: ...`` naming the bad entry
    """
    if reqs is None:
        return dict(DEFAULT_REQUIREMENTS)
    if not reqs:
        raise ValueError("--requirements: give at least one NAME=MDEG")
    out = {}
    for name, v in reqs.items():
        if not isinstance(name, str) or not name or "=" in name:
            raise ValueError(f"--requirements: bad name {name!r}")
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"--requirements: {name}={v!r} is not a number of mdeg") from None
        if not (math.isfinite(x) and x > 0):
            raise ValueError(f"--requirements: {name}={v!r} must be a finite number of mdeg > 0")
        out[name] = x
    return out


def parse_requirements(values: Sequence[str] | None) -> dict[str, float] | None:
    """``--requirements Ka=2 X=8`` as on the command line."""
    if values is None:
        return None
    reqs: dict[str, str] = {}
    for v in values:
        name, eq, val = str(v).partition("=")
        if not eq or not name:
            raise ValueError(f"--requirements: expected NAME=MDEG (e.g. Ka=2), got {v!r}")
        if name in reqs:
            raise ValueError(f"--requirements: {name} given twice")
        reqs[name] = val
    return check_requirements(reqs)


# ------------------------------------------------------------------------------ statistics
def episode_three_sigma(ep: Mapping[str, Any], quantity: str = SERVO) -> float:
    """The larger of the episode's two axes' 3σ of ``quantity`` (the servo error: az, el; the
    pointing error: el, xel), mdeg.
    """
    return max(episode_error(ep, quantity, ax) for ax in ERRORS[quantity])


def completed(ep: Mapping[str, Any]) -> bool:
    """The episode ran to the end: not terminated, no controller failure, a finite 3σ."""
    return not ep["terminated"] and not ep["failures"] and math.isfinite(episode_three_sigma(ep))


def share_ci(k: int, n: int, level: float = 0.95) -> dict[str, Any]:
    """A share ``k / n`` with its Wilson score interval."""
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="wilson")
    return {"share": k / n, "ci95": [float(ci.low), float(ci.high)], "k": int(k), "n": int(n),
            "method": "Wilson score interval"}


def cell_statistics(episodes: Sequence[Mapping[str, Any]], reqs: Mapping[str, float],
                    rng: np.random.Generator) -> dict[str, Any]:
    """The statistics of one controller in one wind condition (module docstring)."""
    done = [ep for ep in episodes if completed(ep)]
    dist: dict[str, Any] = {}
    xs = {}
    for q, key in THREE_SIGMA_KEYS.items():
        if not all(q in ep for ep in done):  # a file written before the quantity was kept
            dist[key] = None
            continue
        x = xs[q] = np.array([episode_three_sigma(ep, q) for ep in done])
        dist[key] = {name: bootstrap_ci(x, stat, rng).as_dict() if x.size >= MIN_UNITS else None
                     for name, stat in QUANTILES.items()}
    x = xs.get(REQUIREMENT_QUANTITY)
    meets: dict[str, Any] = {}
    for name, r in reqs.items():
        share = None if x is None else share_ci(int(np.sum(x <= r)), len(episodes))
        meets[name] = {"requirement_mdeg": r, "quantity": REQUIREMENT_QUANTITY, **(share or {"share": None})}
    return {
        "n_episodes": len(episodes), "n_completed": len(done), **dist, "meets": meets,
        "terminated": int(sum(bool(ep["terminated"]) for ep in episodes)),
        "failures": int(sum(int(ep["failures"]) for ep in episodes)),
        "fallbacks": int(sum(int(ep["fallbacks"]) for ep in episodes)),
        "episodes_with_fallbacks": int(sum(int(ep["fallbacks"]) > 0 for ep in episodes)),
        "limit_hits": {k: int(sum(ep["limit_hits"][k] for ep in episodes)) for k in ("rate", "accel")},
        **{f"worst_plant{'' if q == POINTING else '_servo'}":
           int(done[int(np.argmax(v))]["plant"]) if v.size else None for q, v in xs.items()},
    }


def summarise(spec: Any, episodes: Sequence[Mapping[str, Any]], reqs: Mapping[str, float],
              seed: int = 0) -> dict[str, Any]:
    """``summary[controller][condition]`` (:func:`cell_statistics`) of a campaign's episodes.

    :param spec: the campaign's :class:`dss14_env.bench.campaign.CampaignSpec`
    :param seed: of the bootstrap generators, one per cell: ``default_rng((seed, i, j))``
    """
    by_cell: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for ep in episodes:
        by_cell.setdefault((ep["controller"], ep["condition"]), []).append(ep)
    out: dict[str, Any] = {}
    for i, c in enumerate(spec.names):
        out[c] = {}
        for j, cond in enumerate(spec.conditions):
            eps = sorted(by_cell.get((c, cond.key), []), key=lambda e: e["plant"])
            if len(eps) != spec.plants:
                raise ValueError(f"campaign: {c} in {cond.key} has {len(eps)} episodes, "
                                 f"expected {spec.plants}")
            out[c][cond.key] = cell_statistics(eps, reqs, np.random.default_rng((seed, i, j)))
    return out


def draw_summary(spec: Any, plants: Sequence[Mapping[str, Any]],
                 episodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The plants' draws: the draws rejected before them (by reason, and as a share of all
    draws), and each controller's unstable share -- plants on which one of its episodes
    terminated (the error bound), and, for the report's PI gain sets, plants on which the PI
    loop has a pole at or right of 0 (exact) -- with Wilson intervals.
    """
    rejected: dict[str, int] = {}
    for p in plants:
        for why, n in (p.get("params_rejected") or {}).items():
            rejected[why] = rejected.get(why, 0) + int(n)
    n_rej = sum(rejected.values())
    out: dict[str, Any] = {"condition_on_pi": bool(getattr(spec, "condition_on_pi", True)),
                           "plants": len(plants), "rejected": rejected,
                           "rejected_share": share_ci(n_rej, n_rej + len(plants)) if plants else None}
    bad: dict[str, set] = {c: set() for c in spec.names}
    for ep in episodes:
        if ep["terminated"]:
            bad.setdefault(ep["controller"], set()).add(ep["plant"])
    out["terminated_share"] = {c: share_ci(len(bad[c]), len(plants)) for c in spec.names} if plants else {}
    gains = sorted({g for p in plants for g in (p.get("pi_loop_abscissa") or {})})
    out["pi_unstable_share"] = {g: share_ci(sum(p["pi_loop_abscissa"][g] >= 0 for p in plants
                                                if g in (p.get("pi_loop_abscissa") or {})), len(plants))
                                for g in gains}
    return out


def pi_gain_set(name: str) -> str | None:
    """The report's PI gain set a controller row runs (its catalog row's argument), or None."""
    row = catalog.CONTROLLERS.get(name)
    if row is None or row.cls != "PIController" or not row.args:
        return None
    return str(row.args[0])


def draws_markdown(d: Mapping[str, Any]) -> str:
    """:func:`draw_summary` as a paragraph and a table."""
    def pct(x: Mapping[str, Any]) -> str:
        lo, hi = x["ci95"]
        return f"{100 * x['share']:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] ({x['k']}/{x['n']})"

    how = ("conditioned on the report's PI (kp 1) being stable with a 0.01 1/s margin, as "
           "`randomize_params` draws" if d["condition_on_pi"] else
           "not conditioned on any controller (only the drive's rate loop must be stable)")
    why = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in d["rejected"].items() if v) or "none"
    lines = [f"Plants drawn {how}; draws rejected before them: "
             + (pct(d["rejected_share"]) if d["rejected_share"] else "—") + f" ({why}).", "",
             "| controller | plants with a terminated episode | PI loop unstable (exact) |", "|---|---|---|"]
    for c, x in d["terminated_share"].items():
        exact = d["pi_unstable_share"].get(pi_gain_set(c))
        lines.append(f"| {c} | {pct(x)} | {pct(exact) if exact else '—'} |")
    return "\n".join(lines) + "\n"


#: the per-episode entries the statistics read (:func:`compact_results` keeps only these)
STAT_FIELDS = ("plant", "controller", "condition", "terminated", "failures", "fallbacks", "limit_hits")


def compact_results(results: Mapping[str, Any]) -> dict[str, Any]:
    """results.json less what the statistics do not read: per episode only :data:`STAT_FIELDS`
    and the 3σ pointing and servo errors per axis (a small file to keep with the docs;
    :func:`summarise` on its episodes gives its summary again).
    """
    eps = [{**{k: ep[k] for k in STAT_FIELDS},
            **{q: {ax: {"three_sigma": episode_error(ep, q, ax)} for ax in axes}
               for q, axes in ERRORS.items()}} for ep in results["episodes"]]
    return {**{k: v for k, v in results.items() if k != "episodes"}, "episodes": eps}


# ------------------------------------------------------------------------------ tables
def _est(e: Mapping[str, Any] | None) -> str:
    if e is None:
        return "—"
    lo, hi = e["ci95"]
    return f"{fmt(e['value'])} [{fmt(lo)}, {fmt(hi)}]"


def _pct(x: float) -> str:
    """A share in %: whole numbers, one decimal where that would round to 0 or 100 but is not."""
    p = 100.0 * x
    return f"{p:.0f}" if p == round(p) or 1.0 <= p <= 99.0 else f"{p:.1f}"


def _share(m: Mapping[str, Any]) -> str:
    if m.get("share") is None:
        return "—"
    lo, hi = m["ci95"]
    return f"{_pct(m['share'])} % [{_pct(lo)}, {_pct(hi)}]"


def main_table(results: Mapping[str, Any]) -> str:
    """The Markdown table: per controller and condition the distribution of the 3σ pointing
    error (the headline), the shares that meet each requirement (on the pointing error), the
    distribution of the 3σ servo error at the encoders and the health counts.
    """
    c = results["campaign"]
    reqs = c["requirements_mdeg"]
    spec = CampaignSpec.from_dict(c["spec"])
    header = ["controller", "wind", "pointing: median 3σ", "95th pct", "worst"]
    header += [f"pointing ≤ {v:g} mdeg ({n})" for n, v in reqs.items()]
    header += ["servo: median 3σ", "95th pct", "worst", "terminated", "fallbacks (episodes)", "failures"]
    rows = []
    for ctrl in spec.names:
        for cond in spec.conditions:
            s = results["summary"][ctrl][cond.key]
            ps, ts = s.get(THREE_SIGMA_KEYS[POINTING]) or {}, s.get(THREE_SIGMA_KEYS[SERVO]) or {}
            rows.append([ctrl, cond.label] + [_est(ps.get(q)) for q in QUANTILES]
                        + [_share(s["meets"][n]) for n in reqs]
                        + [_est(ts.get(q)) for q in QUANTILES]
                        + [str(s["terminated"]), f"{s['fallbacks']} ({s['episodes_with_fallbacks']})",
                           str(s["failures"])])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


LEGEND = """\
How to read it: every row is one controller in one wind condition over the campaign's plants,
one hold episode per plant (the same plants, start positions and gusts for every controller).
The pointing 3σ is the larger of the elevation and cross-elevation 3σ of the dish's true
pointing error (command minus the structure's pointing angle, deformation included, after the
warm-up): where the beam points, which is what the Ka- and X-band requirements are about. The
servo 3σ is the larger of the azimuth and elevation 3σ of the true servo error at the drive
encoders, the report's Table 4 quantity. Both in mdeg, over the episodes that ran to the end;
brackets hold 95 % percentile-bootstrap intervals over plants (2000 resamples; the interval of
the worst case cannot exceed the observed worst). "pointing ≤ R mdeg" is the share of all
episodes whose pointing 3σ is at most R on both axes (terminated ones count as missing it),
with a Wilson score interval. Terminated: the servo
error passed the environment's bound or the antenna left its travel. Fallbacks: steps where the
MPC used its LQG action instead of a solution (total, and the episodes with any). Failures:
exceptions raised by the controller.
"""


def results_markdown(results: Mapping[str, Any]) -> str:
    """results.md: the options, the main table, the figures and the legend."""
    c = results["campaign"]
    s = c["spec"]
    ex = c["executor"]
    last = s["first_plant"] + s["plants"] - 1
    where = (f"Ray, {ex.get('workers')} workers" if ex["kind"] == "ray" else "in-process")
    parts = ["# DSS-14 robustness campaign", "",
             f"{s['plants']} plants (indices {s['first_plant']}–{last}) drawn from the report's "
             f"hydraulic parameter ranges (stable part); controllers {', '.join(s['controllers'])}, "
             f"designed on the nominal plant; hold episodes of {s['steps']} steps "
             f"({s['steps'] * control_period():g} s, {s['warmup_s']:g}-s warm-up); "
             f"{counted(c['chunks']['total'], 'chunk')} "
             f"of {counted(s['chunk_size'], 'plant')} "
             f"({c['chunks']['computed']} computed in this run, "
             f"{c['chunks']['resumed']} read back), {where}; wall time "
             f"{c['wall_time_s']['total']:.0f} s.", "",
             "## 3σ pointing error (mdeg) and the pointing requirements; 3σ servo error at the "
             "encoders (mdeg)", "", main_table(results), ""]
    if results.get("draws"):
        parts += ["## Plant draws and unstable shares", "", draws_markdown(results["draws"])]
    if c.get("figures"):
        parts += ["## Cumulative distributions", ""]
        parts += [f"![{f}]({f})" for f in c["figures"]] + [""]
    parts += [LEGEND]
    return "\n".join(parts)


def docs_section(results: Mapping[str, Any], speed: Mapping[str, Any], figure: str) -> str:
    """The measured campaign for the manual: the speed check's line, the table, the figure.

    :param results: the campaign's results (the Ray run's; :func:`compact_results` suffices)
    :param speed: ``speed.json`` of ``scripts/bench_campaign_speed.py``
    :param figure: the CDF figure's path relative to the manual
    """
    c, r = results["campaign"], speed["runs"]
    s = c["spec"]
    loads = [x for run in r.values() for x in (run["load_before"][0], run["load_after"][0])]
    return "\n".join([
        f"`scripts/bench_campaign_speed.py`: {s['plants']} plants × {', '.join(s['controllers'])} × "
        f"50 km/h front and side ({speed['n_episodes']} episodes of {s['steps']} steps, "
        f"{c['chunks']['total']} chunks of {s['chunk_size']}), each run as the command in a fresh "
        f"process on a {speed['cpu_count']}-core machine shared with other jobs (1-min load average "
        f"{min(loads):.1f}–{max(loads):.1f}): in-process {r['serial']['wall_time_s']:.0f} s, local Ray "
        f"with {c['executor']['workers']} CPUs {r['ray']['wall_time_s']:.0f} s, **speed-up "
        f"{speed['speedup']:.2f}×** (one run each, the whole command's wall time); the two "
        f"results.json hold {'identical' if speed['identical_numbers'] else 'DIFFERENT'} numbers "
        f"(every episode's metrics, the plants and the statistics).", "",
        main_table(results), "", f"![CDF of the 3σ {_stored(results)} over plants]({figure})"])


def _stored(results: Mapping[str, Any]) -> str:
    """What the CDF figure of ``results`` shows: both errors, or the servo error alone (a file
    written before the pointing error was kept).
    """
    eps = results["episodes"]
    return "pointing and servo errors" if eps and POINTING in eps[0] else "servo error"


# ------------------------------------------------------------------------------ figures
def cdf_figure_name(speed_kmh: float) -> str:
    return f"cdf_{speed_kmh:g}kmh.png"


def draw_cdfs(results: Mapping[str, Any], out: str | Path) -> list[str]:
    """One PNG per wind speed: per direction, the share of plants whose 3σ pointing error (solid)
    and 3σ servo error at the encoders (dotted) is at most x, one colour per controller, with
    the requirements (on the pointing error) as vertical lines.  Episodes that did not run to
    the end count as never meeting x, so such a curve stays below 1.

    :return: the file names written
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter

    spec = CampaignSpec.from_dict(results["campaign"]["spec"])
    reqs = results["campaign"]["requirements_mdeg"]
    by_cell: dict[tuple[str, str, str], list[float]] = {}
    for ep in results["episodes"]:
        for q in (q for q in THREE_SIGMA_KEYS if q in ep):
            x = episode_three_sigma(ep, q) if completed(ep) else math.inf
            by_cell.setdefault((ep["controller"], ep["condition"], q), []).append(x)
    finite = [x for v in by_cell.values() for x in v if math.isfinite(x)]
    lo = min(finite + list(reqs.values())) / 1.5 if finite else 0.1
    hi = max(finite + list(reqs.values())) * 1.5 if finite else 100.0
    colors = {c: f"C{i % 10}" for i, c in enumerate(spec.names)}
    written = []
    for speed in spec.wind_speeds_kmh:
        conds = [c for c in spec.conditions if c.speed_kmh == speed]
        fig = Figure(figsize=(4.2 * len(conds) + 0.6, 3.6), layout="constrained")
        FigureCanvasAgg(fig)
        axs = fig.subplots(1, len(conds), squeeze=False, sharey=True)[0]
        for axp, cond in zip(axs, conds, strict=True):
            for ctrl in spec.names:
                for q, ls in ((POINTING, "-"), (SERVO, ":")):
                    v = np.sort(np.asarray(by_cell.get((ctrl, cond.key, q), []), float))
                    n = v.size
                    xs = v[np.isfinite(v)]
                    ys = np.arange(1, xs.size + 1) / max(n, 1)
                    axp.step(np.r_[lo, xs, hi], np.r_[0.0, ys, ys[-1] if ys.size else 0.0], where="post",
                             color=colors[ctrl], ls=ls,
                             label=f"{ctrl} {'pointing' if q == POINTING else 'servo'}")
            for name, r in reqs.items():
                axp.axvline(r, color="0.4", ls="--", lw=0.8)
                axp.text(r, 0.02, f" {name} {r:g}", rotation=90, va="bottom", ha="right", fontsize=7,
                         color="0.3")
            axp.set_xscale("log")
            axp.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            axp.set_xlim(lo, hi)
            axp.set_ylim(0, 1.02)
            axp.set_title(f"{cond.label} wind", fontsize=10)
            axp.set_xlabel("3σ, worse axis (mdeg): pointing (solid), servo (dotted)")
            axp.grid(True, which="both", alpha=0.3)
        axs[0].set_ylabel(f"share of {spec.plants} plants ≤ x")
        axs[-1].legend(loc="lower right", fontsize=7)
        name = cdf_figure_name(speed)
        atomic_save_figure(fig, Path(out) / name, dpi=90)
        written.append(name)
    return written


__all__ = ["DEFAULT_REQUIREMENTS", "LEGEND", "REQUIREMENT_QUANTITY", "STAT_FIELDS", "THREE_SIGMA_KEYS",
           "cell_statistics", "pi_gain_set", "check_requirements",
           "compact_results", "completed", "docs_section", "draw_cdfs", "episode_three_sigma", "main_table",
           "package_versions", "parse_requirements", "results_markdown", "share_ci", "summarise"]
