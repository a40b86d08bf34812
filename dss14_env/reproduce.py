"""``dss14 reproduce``: redraw the report's figures and check its published figures.

Writes PNG figures (Figs. 3, 4, 8, 9, 11, 12, 14, 15, 17, 19, 20, 21, 22 of [R]),
``metrics.json`` (one entry per quantity: report, model, accepted, ok) and ``metrics.md``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dss14_env.core.units import AXES, rad_to_mdeg
from dss14_env.model.analysis import (
    bandwidth_hz,
    loop_crossover_hz,
    peak_frequencies,
    spectral_abscissa,
    step,
    step_metrics,
)
from dss14_env.model.assembly import DSS14Model, default_model
from dss14_env.model.board import board_dc_gains, board_ss
from dss14_env.model.calibration import peak_frequency, rate_response, reduction_scales
from dss14_env.model.hydraulics import hydraulics_ss
from dss14_env.model.linsys import freqresp
from dss14_env.model.reduction import hankel_singular_values
from dss14_env.model.uncertainty import stability_sweep
from dss14_env.wind.loads import (
    DIRECTIONS,
    WindLoads,
    default_wind_loads,
    load_wind_config,
    simulate_wind_response,
    three_sigma_estimate,
    three_sigma_mdeg,
)

STEP_T_END, STEP_N = 40.0, 2001
WIND_SPEEDS_KMH = (30.0, 50.0, 70.0)
WIND_SIM = dict(duration=1800.0, dt=0.05, n_records=4)  # 2 h per case: statistical error < 1 %
WIND_SEED = 20261122


def _row(report, model, accepted, note: str = "") -> dict:
    """One metrics entry; ``accepted`` is [lo, hi] (None: reported only)."""
    ok = None if accepted is None else bool(accepted[0] <= model <= accepted[1])
    return {"report": report, "model": float(model), "accepted": accepted, "ok": ok, "note": note}


def compute_metrics(m: DSS14Model, sweep_levels: int = 3) -> dict:
    """Every quantity of the reproduction table, keyed by a stable snake_case name."""
    out: dict[str, dict] = {}
    g_r, _ = board_dc_gains(m.cfg, "az")
    out["board_gr_dc"] = _row(0.3323, g_r, [0.3323 * 0.995, 0.3323 * 1.005], "Eq. (6), A/(rad/s)")
    for ax, rep in (("az", -0.7750e-4), ("el", -0.6525e-4)):
        g_t = board_dc_gains(m.cfg, ax)[1]
        out[f"board_gt_dc_{ax}"] = _row(rep, g_t, sorted([rep * 0.995, rep * 1.005]), "Eq. (8), A/(rad/s)")
    rl = m.rate_loop
    for ax in AXES:
        dc, h03 = rate_response(rl, ax, [1e-4, 0.3])
        out[f"rate_loop_dc_{ax}"] = _row(0.74, dc, [0.70, 0.78], "Fig. 17, r -> encoder rate")
        out[f"rate_loop_0p3hz_{ax}"] = _row(0.74, h03, [0.6, 0.78], "Fig. 17 at 0.3 Hz (flat)")
        tgt = m.cfg.calibration.gearbox_peak[ax]
        out[f"gearbox_peak_hz_{ax}"] = _row(tgt, peak_frequency(rl, ax, 0.5 * tgt, 2 * tgt, 400),
                                            [0.9 * tgt, 1.1 * tgt], "Fig. 17 gearbox resonance")
    s = m.structure.to_ss()
    f = np.geomspace(0.3, 3.0, 6000)
    pk = peak_frequencies(f, np.abs(freqresp(s, f, "enc_rate_az", "T_a")))
    for k, rep in enumerate((1.2, 2.2)):
        near = pk[np.argmin(np.abs(pk - rep))] if pk.size else float("nan")
        out[f"structure_peak{k + 1}_hz_az"] = _row(rep, near, [rep - 0.1, rep + 0.1], "Fig. 15(a)")
    pk_el = peak_frequencies(f, np.abs(freqresp(s, f, "enc_rate_el", "T_e")))
    out["structure_peaks_below_3hz_el"] = _row(0, pk_el.size, [0, 0], "Fig. 15(a): none in el")
    fl = np.geomspace(0.005, 2.0, 3000)
    for gname in m.cfg.gain_sets:
        pl = m.position_loop(gname)
        kp, ki = m.gains(gname)
        for k, (ax, c_in, enc, other) in enumerate((("az", "c_a", "enc_az", "enc_el"),
                                                    ("el", "c_e", "enc_el", "enc_az"))):
            tag = f"{ax}_{gname}"
            out[f"pi_bandwidth_hz_{tag}"] = _row(0.1, bandwidth_hz(pl, enc, c_in), [0.08, 0.2],
                                                 "Fig. 19, -3 dB")
            G = freqresp(rl, fl, enc, "r_a" if ax == "az" else "r_e")
            L = (kp[k] + ki[k] / (2j * np.pi * fl)) * G
            out[f"pi_crossover_hz_{tag}"] = _row(0.1, loop_crossover_hz(L, fl), None,
                                                 "open-loop gain crossover (reported only)")
            t, y = step(pl, c_in, [enc, other], STEP_T_END, STEP_N)
            sm = step_metrics(t, y[:, 0])
            out[f"pi_overshoot_pct_{tag}"] = _row("20-30", sm["overshoot_pct"], [15, 35], "Fig. 21")
            out[f"pi_settling_2pct_s_{tag}"] = _row("7-9", sm["settling_2pct_s"], [0, 12], "Fig. 21, 2 %")
            out[f"pi_settling_5pct_s_{tag}"] = _row("7-9", sm["settling_5pct_s"], None, "Fig. 21, 5 % (reported only)")
            out[f"cross_coupling_{ax}_step_{gname}"] = _row(1e-3, float(np.max(np.abs(y[:, 1]))),
                                                            [1e-4, 5e-3], f"Fig. 22, peak {other} per unit {ax} step")
        out[f"stable_position_loop_{gname}"] = _row("stable", spectral_abscissa(pl), [-math.inf, 0.0],
                                                    "Eq. (61): largest pole real part, 1/s")
    sw = stability_sweep(m, levels=sweep_levels)
    for gname, v in sw["gain_sets"].items():
        out[f"sweep_stable_share_{gname}"] = _row("-", v["stable_share"], None,
                                                  f"{sw['n']} combinations of {', '.join(sw['params'])}")
        out[f"sweep_worst_abscissa_{gname}"] = _row("-", v["worst_abscissa"], None,
                                                    "largest pole real part over the sweep, 1/s")
    return out


def compute_wind_metrics(m: DSS14Model, loads: WindLoads | None = None, gain_set: str = "kp1",
                         seed: int = WIND_SEED, sim: dict | None = None) -> tuple[dict, dict]:
    """[R] Table 4: 3-sigma encoder servo errors of the PI loop in wind, report vs model.

    For each direction, the exact stationary figure (Lyapunov, :func:`three_sigma_mdeg`) at 30,
    50 and 70 km/h, and at 50 km/h also the figure of a time-domain simulation
    (:func:`simulate_wind_response`, ``sim`` settings, default :data:`WIND_SIM`) with its
    statistical error (batch means).

    :return: ``(rows, records)``: metrics rows keyed ``wind_3sigma_mdeg_<axis>_<direction>``
        (50 km/h, time domain, with the accepted range), ``..._lyap`` (50 km/h, exact),
        ``..._<speed>kmh`` (other speeds, exact, reported only); and the simulated servo-error
        records (mdeg) per direction for plotting.
    """
    loads = loads if loads is not None else default_wind_loads()
    wcfg = load_wind_config()
    sim = dict(WIND_SIM, **(sim or {}))
    pl = m.position_loop(gain_set)
    rng = np.random.default_rng(seed)
    rows: dict[str, dict] = {}
    records: dict[str, np.ndarray] = {}
    for d in DIRECTIONS:
        y = simulate_wind_response(pl, loads, wcfg.table4.speed, d, sim["duration"], sim["dt"], rng,
                                   n_records=sim["n_records"])
        ts, rel = three_sigma_estimate(y)
        ts = rad_to_mdeg(ts)
        records[d] = rad_to_mdeg(y[0])
        exact = {v: three_sigma_mdeg(pl, loads, v / 3.6, d) for v in WIND_SPEEDS_KMH}
        for k, ax in enumerate(("az", "el")):
            p = wcfg.params[f"table4.{ax}_{d}"]
            rep, acc = rad_to_mdeg(p.value), [rad_to_mdeg(v) for v in p.range]
            hours = sim["duration"] * sim["n_records"] / 3600.0
            rows[f"wind_3sigma_mdeg_{ax}_{d}"] = _row(
                round(rep, 3), ts[k], [round(a, 3) for a in acc],
                f"Table 4, 50 km/h, PI {gain_set}: {hours:g} h simulated, stat. error {100 * rel[k]:.1f} %")
            rows[f"wind_3sigma_mdeg_{ax}_{d}_lyap"] = _row(
                round(rep, 3), exact[50.0][k], [round(a, 3) for a in acc],
                "Table 4, 50 km/h: exact stationary value (Lyapunov)")
            for v in WIND_SPEEDS_KMH:
                if v != 50.0:
                    rows[f"wind_3sigma_mdeg_{ax}_{d}_{v:.0f}kmh"] = _row(
                        "-", exact[v][k], None, f"{v:.0f} km/h, exact (reported only)")
    return rows, records


def draw_wind_figures(loads: WindLoads, records: dict, dt: float, out: Path) -> list[str]:
    """Gust PSD vs the Davenport formula and the shaping filter; servo-error time histories."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dss14_env.wind.gusts import plot_gust_psd

    wcfg = load_wind_config()
    plot_gust_psd(wcfg.table4.speed, np.random.default_rng(WIND_SEED), out / "wind_gust_psd.png",
                  duration=2 * 3600.0, order=loads.cfg.filter_order, kappa=loads.cfg.davenport_kappa,
                  length=loads.cfg.davenport_length)
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    n = min(int(round(600.0 / dt)), next(iter(records.values())).shape[0])
    t = np.arange(n) * dt
    for axp, (d, y) in zip(axes, records.items()):
        axp.plot(t, y[:n, 0], lw=0.7, label="azimuth")
        axp.plot(t, y[:n, 1], lw=0.7, label="elevation")
        axp.set_ylabel(f"{d} wind: servo error, mdeg")
        axp.grid(True, alpha=0.3)
        axp.legend(loc="upper right")
    axes[-1].set_xlabel("time, s")
    fig.suptitle("Encoder servo errors, PI kp 1 ki 0.3, 50 km/h Davenport gusts (Table 4)")
    fig.tight_layout()
    fig.savefig(out / "wind_servo_errors.png", dpi=90)
    plt.close(fig)
    return ["wind_gust_psd.png", "wind_servo_errors.png"]


def metrics_markdown(metrics: dict) -> str:
    """The metrics as a Markdown table."""
    lines = ["| quantity | report | model | accepted | ok |", "|---|---|---|---|---|"]
    for k, v in metrics.items():
        acc = "—" if v["accepted"] is None else f"{_fmt(v['accepted'][0])} … {_fmt(v['accepted'][1])}"
        ok = "—" if v["ok"] is None else ("yes" if v["ok"] else "**NO**")
        lines.append(f"| `{k}` | {v['report']} | {_fmt(v['model'])} | {acc} | {ok} |")
    return "\n".join(lines) + "\n"


def _fmt(x) -> str:
    if isinstance(x, str):
        return x
    if x in (math.inf, -math.inf):
        return "∞" if x > 0 else "−∞"
    return f"{x:.4g}"


# ------------------------------------------------------------------------------ figures
def _bode(ax_mag, f, curves, ylabel="magnitude", ax_phase=None):
    for label, h in curves:
        ax_mag.loglog(f, np.abs(h), label=label)
        if ax_phase is not None:
            ax_phase.semilogx(f, np.degrees(np.unwrap(np.angle(h))), label=label)
    ax_mag.set_ylabel(ylabel)
    ax_mag.grid(True, which="both", alpha=0.3)
    ax_mag.legend()
    (ax_phase or ax_mag).set_xlabel("frequency, Hz")
    if ax_phase is not None:
        ax_phase.set_ylabel("phase, deg")
        ax_phase.grid(True, which="both", alpha=0.3)


def draw_figures(m: DSS14Model, out: Path) -> list[str]:
    """Draw the report's figures into ``out``; return the file names."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []

    def save(fig, name, title):
        fig.suptitle(title)
        fig.tight_layout()
        fig.savefig(out / name, dpi=90)
        plt.close(fig)
        files.append(name)

    f = np.geomspace(1e-3, 100, 600)
    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 6))
    _bode(a, f, [("az (el identical)", freqresp(board_ss(m.cfg, "az"), f, "i", "r"))], "A/(rad/s)", b)
    save(fig, "fig03_board_r_to_i.png", "Fig. 3: board, rate command r -> current i")
    fig, a = plt.subplots(figsize=(7, 4))
    _bode(a, f, [(ax, freqresp(board_ss(m.cfg, ax), f, "i", "tach_rate")) for ax in AXES], "A/(rad/s)")
    save(fig, "fig04_board_tach_to_i.png", "Fig. 4: board, tach rate -> current i")
    fh = np.geomspace(1e-2, 1e3, 600)
    hyd = {ax: hydraulics_ss(m.drive_params(ax).hydraulics, ax) for ax in AXES}
    fig, a = plt.subplots(figsize=(7, 4))
    _bode(a, fh, [(ax, freqresp(hyd[ax], fh, "T_o", "i")) for ax in AXES], "N*m/A")
    save(fig, "fig08_hydraulics_i_to_To.png", "Fig. 8: hydraulics, current -> motor torque")
    fig, a = plt.subplots(figsize=(7, 4))
    _bode(a, fh, [(ax, freqresp(hyd[ax], fh, "T_o", "motor_rate")) for ax in AXES], "N*m/(rad/s)")
    save(fig, "fig09_hydraulics_wm_to_To.png", "Fig. 9: hydraulics, motor rate -> motor torque")
    drv = {ax: m.drive(ax) for ax in AXES}
    fig, a = plt.subplots(figsize=(7, 4))
    _bode(a, fh, [(ax, freqresp(drv[ax], fh, "T", "r")) for ax in AXES], "N*m/(rad/s)")
    save(fig, "fig11_drive_r_to_T.png", "Fig. 11: drive, rate command -> pinion torque")
    fig, a = plt.subplots(figsize=(7, 4))
    _bode(a, fh, [(ax, freqresp(drv[ax], fh, "T", "pinion_rate")) for ax in AXES], "N*m/(rad/s)")
    save(fig, "fig12_drive_wp_to_T.png", "Fig. 12: drive, pinion rate -> pinion torque")
    full = m.structure_full
    hsv = hankel_singular_values(full, **reduction_scales(m.cfg, full))
    fig, a = plt.subplots(figsize=(7, 4))
    fr = full.omega / (2 * np.pi)
    flex = np.isfinite(hsv)
    kept = np.zeros(full.n_modes, bool)
    kept[m.kept_modes] = True
    a.semilogy(fr[flex & ~kept], hsv[flex & ~kept], "o", ms=3, label="truncated")
    a.semilogy(fr[flex & kept], hsv[flex & kept], "s", ms=5, label="kept (22 flexible)")
    a.set_xscale("log")
    a.set_xlabel("natural frequency, Hz")
    a.set_ylabel("Hankel singular value, Eq. (55)")
    a.grid(True, which="both", alpha=0.3)
    a.legend()
    save(fig, "fig14_hankel_singular_values.png", "Fig. 14: Hankel singular values of the 150 modes")
    s = m.structure.to_ss()
    fs = np.geomspace(0.1, 100, 3000)
    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 7))
    _bode(a, fs, [("az: T_a -> az rate", freqresp(s, fs, "enc_rate_az", "T_a")),
                  ("el: T_e -> el rate", freqresp(s, fs, "enc_rate_el", "T_e"))], "(rad/s)/(N*m)")
    a.set_title("(a) direct")
    _bode(b, fs, [("T_a -> el rate", freqresp(s, fs, "enc_rate_el", "T_a")),
                  ("T_e -> az rate", freqresp(s, fs, "enc_rate_az", "T_e"))], "(rad/s)/(N*m)")
    b.set_title("(b) cross-coupling")
    save(fig, "fig15_structure.png", "Fig. 15: structure, pinion torque -> axis (encoder) rate")
    rl = m.rate_loop
    fr = np.geomspace(1e-3, 100, 1500)
    fig, a = plt.subplots(figsize=(7, 4))
    _bode(a, fr, [("az", freqresp(rl, fr, "enc_rate_az", "r_a")),
                  ("el", freqresp(rl, fr, "enc_rate_el", "r_e"))], "(rad/s)/(rad/s)")
    save(fig, "fig17_rate_loop.png", "Fig. 17: rate loop, rate command -> encoder rate")
    fc = np.geomspace(1e-3, 10, 1200)
    pls = {g: m.position_loop(g) for g in m.cfg.gain_sets}
    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 7))
    _bode(a, fc, [(f"az {g}", freqresp(pl, fc, "enc_az", "c_a")) for g, pl in pls.items()])
    _bode(b, fc, [(f"el {g}", freqresp(pl, fc, "enc_el", "c_e")) for g, pl in pls.items()])
    save(fig, "fig19_closed_loop.png", "Fig. 19: closed loop, command -> encoder")
    fig, a = plt.subplots(figsize=(7, 4))
    _bode(a, fc, [(f"{o} <- {i} {g}", freqresp(pl, fc, o, i)) for g, pl in pls.items()
                  for i, o in (("c_a", "enc_el"), ("c_e", "enc_az"))])
    save(fig, "fig20_closed_loop_cross.png", "Fig. 20: closed loop cross-coupling")
    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 7))
    fig2, (a2, b2) = plt.subplots(2, 1, figsize=(7, 7))
    for g, pl in pls.items():
        for axp, axc, c_in, enc, oth in ((a, a2, "c_a", "enc_az", "enc_el"), (b, b2, "c_e", "enc_el", "enc_az")):
            t, y = step(pl, c_in, [enc, oth], STEP_T_END, STEP_N)
            axp.plot(t, y[:, 0], label=g)
            axc.plot(t, y[:, 1], label=g)
    for axx, lab in ((a, "az encoder (az step)"), (b, "el encoder (el step)"),
                     (a2, "el encoder (az step)"), (b2, "az encoder (el step)")):
        axx.set_ylabel(lab)
        axx.set_xlabel("time, s")
        axx.grid(True, alpha=0.3)
        axx.legend()
    save(fig, "fig21_step.png", "Fig. 21: closed-loop unit step responses")
    save(fig2, "fig22_step_cross.png", "Fig. 22: cross-coupling step responses")
    return files


def _gust_sigma(loads: WindLoads) -> dict:
    """Standard deviation of the gust torques at the Table 4 speed, N*m (for the record)."""
    from dss14_env.wind.gusts import filter_variance
    u = load_wind_config().table4.speed
    sd = math.sqrt(filter_variance(loads.gust_filter(u)))
    return {d: (np.abs(loads.gust_gain(u, d)) * sd).tolist() for d in DIRECTIONS}


def reproduce(out_dir: str | Path, model: DSS14Model | None = None, figures: bool = True) -> dict:
    """Run the reproduction: metrics (json, md) and figures into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    m = model if model is not None else default_model()
    metrics = compute_metrics(m)
    loads = default_wind_loads() if model is None else None
    if loads is None:  # a user model: calibrate its own wind loads
        from dss14_env.wind.loads import calibrate_wind_loads
        loads = calibrate_wind_loads(m)
    wind_rows, records = compute_wind_metrics(m, loads)
    metrics.update(wind_rows)
    (out / "metrics.json").write_text(json.dumps(
        {"metrics": metrics, "calibrated": m.derived(),
         "wind_loads": {"c_front_az_el": loads.c_front.tolist(), "c_side_az_el": loads.c_side.tolist(),
                        "gust_torque_sigma_Nm_50kmh": _gust_sigma(loads)},
         "config": m.cfg.path}, indent=2, default=float))
    md = metrics_markdown(metrics)
    (out / "metrics.md").write_text("# DSS-14 model vs report\n\n" + md)
    files = draw_figures(m, out) + draw_wind_figures(loads, records, WIND_SIM["dt"], out) if figures else []
    return {"metrics": metrics, "markdown": md, "figures": files}
