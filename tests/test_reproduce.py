"""``dss14 reproduce`` on the calibrated model: the report's figures, its exit code and outputs.

Expected values are the report's numbers ([R] Figs. 15-22, Eqs. 6 and 8) and the accepted
ranges decided for them (docs/model.md section 8), written here, not taken from the code under
test.  Tests named ``test_regression_calibrated_*`` re-check a quantity the calibration solves
for: they catch a broken calibration, they are not evidence that the model is right.  The
other tests check consequences the calibration does not set.

The whole command runs once per module (``run`` fixture, about 15 s on 2 cores) without the
viscosity sensitivity (two more calibrations, which do not decide the exit code); the slow test
``test_viscosity_sensitivity_matches_the_committed_results`` runs that part.  The tests read
the command's ``metrics.json``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dss14_env import reproduce as rep
from dss14_env.cli import main
from dss14_env.core.schema import default_config_path
from dss14_env.model import default_model
from dss14_env.model.analysis import dc_gain
from dss14_env.model.linsys import freqresp

GAINS = ["kp1", "kp0.7"]
AXES = ["az", "el"]
REPORT_BANDWIDTH_HZ = 0.1  # [R] text after Fig. 19
ACCEPTED_BANDWIDTH_HZ = (0.08, 0.25)  # -3 dB, every axis and gain set (docs/model.md section 8)
ACCEPTED_CROSSOVER_HZ = (0.07, 0.15)  # gain crossover: the primary match to "0.1 Hz"
RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results" / "reproduce_metrics.json"


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> dict:
    """``dss14 reproduce --out DIR`` on the shipped configuration, with ``matplotlib.use``
    made to fail: the figure code must not switch backends."""
    import matplotlib

    out = tmp_path_factory.mktemp("reproduce")

    def no_use(*args, **kwargs):
        raise AssertionError("matplotlib.use() called by library code")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(matplotlib, "use", no_use)
        mp.setattr(rep, "SENSITIVITY_MU_KPAS", ())  # nominal row only; see the module docstring
        import io
        from contextlib import redirect_stderr, redirect_stdout
        so, se = io.StringIO(), io.StringIO()
        with redirect_stdout(so), redirect_stderr(se):
            rc = main(["reproduce", "--out", str(out)])
    data = json.loads((out / "metrics.json").read_text())
    return {"rc": rc, "out": out, "data": data, "metrics": data["metrics"], "stdout": so.getvalue(),
            "stderr": se.getvalue()}


@pytest.fixture(scope="module")
def metrics(run: dict) -> dict:
    return run["metrics"]


def val(metrics: dict, key: str) -> float:
    return metrics[key]["model"]


# ------------------------------------------------------------------ the command
def test_default_config_exits_0_with_every_accepted_row_inside(run: dict) -> None:
    assert run["rc"] == 0, run["stderr"]
    assert rep.failed_rows(run["metrics"]) == []
    assert "every row with an accepted range is inside it" in run["stdout"]
    with_range = [k for k, v in run["metrics"].items() if v["accepted"] is not None]
    assert len(with_range) >= 40


def test_reproduce_writes_outputs(run: dict) -> None:
    out = run["out"]
    for key, row in run["metrics"].items():
        assert set(row) >= {"report", "model", "accepted", "ok", "note", "calibrated"}, key
    assert set(run["data"]) >= {"metrics", "rate_loop_poles", "viscosity_sensitivity", "wind_loads",
                                "calibrated", "config"}
    md = (out / "metrics.md").read_text()
    assert md.count("|") > 100 and "Rate-loop poles" in md and "Wind moment coefficients" in md
    files = sorted(p.name for p in out.glob("*.png"))
    for fig in (3, 4, 8, 9, 11, 12, 14, 15, 17, 19, 20, 21, 22):
        assert any(f.startswith(f"fig{fig:02d}_") for f in files), fig
    assert {"wind_gust_psd.png", "wind_servo_errors.png"} <= set(files)
    for f in files:
        assert (out / f).stat().st_size > 10_000


def test_fig17_is_a_bode_plot_with_phase() -> None:
    fig = rep.rate_loop_figure(default_model())
    mag, phase = fig.axes
    assert phase.get_ylabel() == "phase, deg"
    for ax in (mag, phase):
        assert [ln.get_label() for ln in ax.get_lines()] == ["az", "el"]
    az_phase = phase.get_lines()[0]
    f, deg = az_phase.get_xdata(), az_phase.get_ydata()
    assert deg[0] == pytest.approx(0.0, abs=1.0)  # DC: no lag
    assert np.interp(0.3, f, deg) < -10.0  # the az lag at 0.3 Hz (the model's own; [R] prints no phase)


def test_config_that_breaks_a_row_exits_1_naming_it(tmp_path: Path, capsys, monkeypatch) -> None:
    """A model configuration whose rate-loop calibration target is 0.85 instead of [R]'s 0.74:
    the rate-loop DC rows leave their 0.70-0.78 range; everything is still written, then the
    command exits 1 and names the rows.  (The viscosity sensitivity, two more calibrations, is
    skipped to keep the test short; it does not decide the exit code.)"""
    text = default_config_path().read_text()
    old = 'rate_loop_dc:        {value: 0.74,'
    assert old in text
    cfg = tmp_path / "model.yaml"
    cfg.write_text(text.replace(old, 'rate_loop_dc:        {value: 0.85,'))
    monkeypatch.setattr(rep, "SENSITIVITY_MU_KPAS", ())
    rc = main(["reproduce", "--out", str(tmp_path / "out"), "--config", str(cfg), "--no-figures"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "rate_loop_dc_az" in err and "rate_loop_dc_el" in err
    assert "outside the accepted range" in err
    data = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert data["metrics"]["rate_loop_dc_az"]["ok"] is False
    assert data["metrics"]["rate_loop_dc_az"]["model"] == pytest.approx(0.85, rel=1e-3)
    assert (tmp_path / "out" / "metrics.md").is_file()


def test_failed_rows_names_out_of_range_and_nan_rows() -> None:
    rows = {"inside": rep._row(1, 1.0, [0.5, 1.5]), "above": rep._row(1, 2.0, [0.5, 1.5]),
            "nan": rep._row(1, float("nan"), [0.5, 1.5]), "reported": rep._row(1, 9.0, None)}
    assert rep.failed_rows(rows) == ["above", "nan"]


def test_cli_bad_config_is_clear(tmp_path, capsys) -> None:
    rc = main(["reproduce", "--out", str(tmp_path), "--config", str(tmp_path / "missing.yaml")])
    assert rc == 2
    assert "missing.yaml" in capsys.readouterr().err


# ------------------------------------------------------------------ regression checks of the calibration
@pytest.mark.parametrize("axis", AXES)
def test_regression_calibrated_rate_loop_flat_074(metrics: dict, axis: str) -> None:
    """Fig. 17: 0.74 below 0.3 Hz; the calibration solves DC = 0.74, |H(0.3 Hz)| = 0.9 DC."""
    assert val(metrics, f"rate_loop_dc_{axis}") == pytest.approx(0.74, rel=1e-3)
    assert val(metrics, f"rate_loop_0p3hz_{axis}") == pytest.approx(0.9 * 0.74, rel=1e-3)
    assert metrics[f"rate_loop_dc_{axis}"]["calibrated"] is True


@pytest.mark.parametrize("axis,hz", [("az", 8.0), ("el", 20.0)])
def test_regression_calibrated_gearbox_peak(metrics: dict, axis: str, hz: float) -> None:
    assert val(metrics, f"gearbox_peak_hz_{axis}") == pytest.approx(hz, rel=0.01)


@pytest.mark.parametrize("k,hz", [(1, 1.2), (2, 2.2)])
def test_regression_calibrated_structure_az_resonances(metrics: dict, k: int, hz: float) -> None:
    assert abs(val(metrics, f"structure_peak{k}_hz_az") - hz) <= 0.02


def test_regression_calibrated_cross_coupling_az_to_el_kp1(metrics: dict) -> None:
    """Fig. 22 "of the order 1e-3": the product of inertia is solved for 1e-3 with kp 1."""
    assert val(metrics, "cross_coupling_az_step_kp1") == pytest.approx(1e-3, rel=2e-3)


# ------------------------------------------------------------------ consequences
@pytest.mark.parametrize("key,report", [("board_gr_dc", 0.3323), ("board_gt_dc_az", -0.7750e-4),
                                        ("board_gt_dc_el", -0.6525e-4)])
def test_board_dc(metrics: dict, key: str, report: float) -> None:
    assert val(metrics, key) == pytest.approx(report, rel=5e-3)


def test_no_el_structure_resonance_below_3hz(metrics: dict) -> None:
    assert val(metrics, "structure_peaks_below_3hz_el") == 0


@pytest.mark.parametrize("kp,ki,bw,fc,ts2,ts5", [(1.0, 0.3, 0.162, 0.126, 10.7, 9.1),
                                                   (0.7, 0.2, 0.123, 0.092, 12.6, 11.3)])
def test_ideal_flat_loop_figures(kp: float, ki: float, bw: float, fc: float, ts2: float, ts5: float) -> None:
    """docs/model.md section 8: with an ideal flat 0.74 rate loop, L = 0.74 (kp s + ki) / s^2,
    kp 1 already has its -3 dB point at 0.16 Hz, so [R]'s "0.1 Hz" is not a literal -3 dB
    figure; its gain crossover is near 0.1 Hz; it settles (2 %) in 10.7 / 12.6 s.  Computed
    here with scipy.signal, independently of the package."""
    import scipy.signal
    num, den = [0.74 * kp, 0.74 * ki], [1.0, 0.74 * kp, 0.74 * ki]
    f = np.geomspace(1e-3, 2.0, 200001)
    _, h = scipy.signal.freqs(num, den, worN=2 * np.pi * f)
    assert f[np.argmax(np.abs(h) < 10 ** (-3 / 20))] == pytest.approx(bw, abs=0.001)
    _, loop = scipy.signal.freqs(num, [1.0, 0.0, 0.0], worN=2 * np.pi * f)
    assert f[np.argmax(np.abs(loop) < 1.0)] == pytest.approx(fc, abs=0.001)
    t = np.linspace(0.0, 40.0, 40001)
    _, y = scipy.signal.step(scipy.signal.lti(num, den), T=t)
    for band, ts in ((0.02, ts2), (0.05, ts5)):
        assert t[np.flatnonzero(np.abs(y - 1) > band)[-1]] == pytest.approx(ts, abs=0.05)


@pytest.mark.parametrize("gs", GAINS)
@pytest.mark.parametrize("axis", AXES)
def test_pi_crossover_matches_report_bandwidth(metrics: dict, axis: str, gs: str) -> None:
    """[R]'s "bandwidth of 0.1 Hz", read as the open-loop gain crossover."""
    lo, hi = ACCEPTED_CROSSOVER_HZ
    assert lo <= val(metrics, f"pi_crossover_hz_{axis}_{gs}") <= hi
    assert abs(val(metrics, f"pi_crossover_hz_{axis}_{gs}") - REPORT_BANDWIDTH_HZ) <= 0.05


@pytest.mark.parametrize("gs", GAINS)
@pytest.mark.parametrize("axis", AXES)
def test_pi_minus_3db_bandwidth(metrics: dict, axis: str, gs: str) -> None:
    lo, hi = ACCEPTED_BANDWIDTH_HZ
    assert lo <= val(metrics, f"pi_bandwidth_hz_{axis}_{gs}") <= hi


@pytest.mark.parametrize("axis", AXES)
def test_lower_gain_gives_lower_bandwidth_and_crossover(metrics: dict, axis: str) -> None:
    """kp 0.7, ki 0.2 is a scaled-down kp 1, ki 0.3: both frequencies drop, by about 0.7."""
    for key in ("pi_bandwidth_hz", "pi_crossover_hz"):
        r = val(metrics, f"{key}_{axis}_kp0.7") / val(metrics, f"{key}_{axis}_kp1")
        assert 0.55 < r < 0.85, key


@pytest.mark.parametrize("gs", GAINS)
@pytest.mark.parametrize("axis", AXES)
def test_peak_T_and_phase_margin_agree_at_the_crossover(metrics: dict, axis: str, gs: str) -> None:
    """Where |L| = 1, |T| = |L / (1 + L)| = 1 / (2 sin(PM / 2)): the closed loop (Eq. 61,
    both axes closed) evaluated at the reported crossover gives the reported phase margin;
    and the reported peak |T| is at least that value."""
    fc = val(metrics, f"pi_crossover_hz_{axis}_{gs}")
    pm = math.radians(val(metrics, f"pi_phase_margin_deg_{axis}_{gs}"))
    enc, c_in = ("enc_az", "c_a") if axis == "az" else ("enc_el", "c_e")
    t_fc = abs(freqresp(default_model().position_loop(gs), [fc], enc, c_in)[0])
    assert t_fc == pytest.approx(1.0 / (2.0 * math.sin(pm / 2.0)), rel=0.01)
    assert val(metrics, f"pi_peak_T_db_{axis}_{gs}") >= 20 * math.log10(t_fc) - 1e-6
    assert 30.0 < math.degrees(pm) < 75.0  # 20-30 % overshoot goes with margins of this order


ENCODER_OUTPUTS = {"drive": ("enc_az", "enc_el"), "axis": ("point_xel", "point_el")}
COS_E = math.cos(math.radians(45.0))  # the shipped structure's elevation
KP1 = ((1.0, 1.0), (0.3, 0.3))  # [R]'s first gain set: kp 1 1/s, ki 0.3 1/s^2


@pytest.mark.parametrize("enc", ["drive", "axis"])
@pytest.mark.parametrize("axis", AXES)
def test_highest_gain_pi_loop_keeps_45_deg_and_no_more(metrics: dict, axis: str, enc: str) -> None:
    """[R]'s conclusion (drive encoders 0.1 Hz; encoders close to the axes 0.7-1.0 Hz): the
    rows of the PI at the highest gain with >= 45 deg margin and a stable closed loop.  Checked
    here on loops built independently: at the reported gains the closed loop is stable, |T| at
    the reported crossover is 1 / (2 sin(PM / 2)) for the reported margin PM >= 45 deg, |T| at
    the reported -3 dB bandwidth is 3 dB below DC, and 3 % more gain leaves less than 45 deg or
    an unstable closed loop (dense grid, no interpolation).  On the stiffer shipped drive the
    boundary can be the closed loop's stability (a lightly damped resonance) while the margin at
    the first crossover is still above 45 deg, so the margin is not pinned to 45 deg."""
    k, tag = AXES.index(axis), f"{enc}_{axis}"
    g = val(metrics, f"pi_pm45_gain_factor_{tag}")
    fc, bw = val(metrics, f"pi_pm45_crossover_hz_{tag}"), val(metrics, f"pi_pm45_bandwidth_hz_{tag}")
    pm = val(metrics, f"pi_pm45_phase_margin_deg_{tag}")
    assert pm >= 45.0
    assert g > 1.0 and fc > val(metrics, f"pi_crossover_hz_{axis}_kp1")  # [R]'s gains keep > 45 deg
    m = default_model()
    out, c_in, r_in = ENCODER_OUTPUTS[enc][k], ("c_a", "c_e")[k], ("r_a", "r_e")[k]
    sc = [1.0 / COS_E if enc == "axis" else 1.0, 1.0]  # axis encoder az: xel / cos(E)

    def loop(factor: float):
        f = [factor if i == k else 1.0 for i in range(2)]
        return rep.position_loop(m.rate_loop, tuple(f[i] * KP1[0][i] * sc[i] for i in range(2)),
                                 tuple(f[i] * KP1[1][i] * sc[i] for i in range(2)), ENCODER_OUTPUTS[enc])

    pl = loop(g)
    assert rep.spectral_abscissa(pl) < 0.0
    t = np.abs(freqresp(pl, [1e-4, fc, bw], out, c_in))
    assert t[1] == pytest.approx(1.0 / (2.0 * math.sin(math.radians(pm / 2))), rel=0.02)
    assert t[2] / t[0] == pytest.approx(10 ** (-3 / 20), rel=0.01)
    fd = np.geomspace(0.02, 3.0, 40000)
    L = 1.03 * g * (KP1[0][k] + KP1[1][k] / (2j * np.pi * fd)) * freqresp(m.rate_loop, fd, out, r_in) * sc[k]
    i = int(np.argmax(np.abs(L) < 1.0))
    ph = np.degrees(np.unwrap(np.angle(L)))
    ph -= 360.0 * np.ceil(ph[0] / 360.0)
    assert 180.0 + ph[i] < 45.0 or rep.spectral_abscissa(loop(1.03 * g)) >= 0.0


def _ideal_flat_settling_2pct_s(kp: float, ki: float, dc: float) -> float:
    """2 % settling of the PI loop around a flat rate loop of gain ``dc``, written out: closed
    loop dc (kp s + ki) / (s^2 + dc kp s + dc ki), last time outside 1 +- 0.02 on a 1 ms grid."""
    import scipy.signal

    t = np.arange(0.0, 60.0, 1e-3)
    _, y = scipy.signal.step(([dc * kp, dc * ki], [1.0, dc * kp, dc * ki]), T=t)
    return float(t[np.nonzero(np.abs(y - 1.0) > 0.02)[0][-1] + 1])


@pytest.mark.parametrize("gs", GAINS)
@pytest.mark.parametrize("axis", AXES)
def test_pi_step(metrics: dict, axis: str, gs: str) -> None:
    """Fig. 21: 20-30 % overshoot ([R]; accepted 15-35 %), 7-9 s settling.  No flat loop of
    Fig. 17's gain 0.74 settles in 7-9 s with [R]'s gains (about 10.7 s with kp 1, 12.6 s with
    kp 0.7), so the 2 % settling is accepted within 1.1 x that ideal loop's (docs/model.md
    section 8); the 5 % settling is no later than the 2 %."""
    kp, ki = {"kp1": (1.0, 0.3), "kp0.7": (0.7, 0.2)}[gs]  # [R]'s two gain sets
    assert 15 <= val(metrics, f"pi_overshoot_pct_{axis}_{gs}") <= 35
    assert val(metrics, f"pi_settling_2pct_s_{axis}_{gs}") <= 1.1 * _ideal_flat_settling_2pct_s(kp, ki, 0.74)
    assert val(metrics, f"pi_settling_5pct_s_{axis}_{gs}") <= val(metrics, f"pi_settling_2pct_s_{axis}_{gs}")


@pytest.mark.parametrize("axis,gs", [("el", "kp1"), ("az", "kp0.7"), ("el", "kp0.7")])
def test_cross_coupling_not_calibrated(metrics: dict, axis: str, gs: str) -> None:
    """Fig. 22 "of the order 1e-3" for the rows the calibration does not set."""
    assert 1e-4 <= val(metrics, f"cross_coupling_{axis}_step_{gs}") <= 5e-3
    assert metrics[f"cross_coupling_{axis}_step_{gs}"]["calibrated"] is False


@pytest.mark.parametrize("gs", GAINS)
def test_cross_coupling_el_to_az_follows_the_load_compliances(metrics: dict, gs: str) -> None:
    """The az-el coupling is a product of inertia J_ae (symmetric): an el step puts J_ae
    times the el acceleration on the az axis and vice versa.  With step responses of similar
    shape on both axes, el -> az over az -> el is about the az over el compliance of the rate
    loop to load torque (DC rate per N*m), within 25 %."""
    rl = default_model().rate_loop
    compliance = abs(dc_gain(rl, "enc_rate_az", "Tw_az") / dc_gain(rl, "enc_rate_el", "Tw_el"))
    ratio = val(metrics, f"cross_coupling_el_step_{gs}") / val(metrics, f"cross_coupling_az_step_{gs}")
    assert 0.8 < ratio / compliance < 1.25


@pytest.mark.parametrize("gs", GAINS)
def test_nominal_loops_stable(metrics: dict, gs: str) -> None:
    assert val(metrics, f"stable_position_loop_{gs}") < 0
    poles = np.linalg.eigvals(default_model().position_loop(gs).A)
    assert np.all(poles.real < 0)


@pytest.mark.parametrize("gs", GAINS)
def test_sweep_reports_share_and_margin(metrics: dict, gs: str) -> None:
    share = val(metrics, f"sweep_stable_share_{gs}")
    assert 0.0 < share <= 1.0
    assert np.isfinite(val(metrics, f"sweep_worst_abscissa_{gs}"))


def test_sweep_finds_low_viscosity_instability() -> None:
    """docs/model.md: high leakage (low mu, high k_a2) with the lowest valve gain is unstable
    with kp 1, and the nominal point is stable."""
    from dss14_env.model.loops import position_loop
    from dss14_env.model.uncertainty import perturbed_rate_loop
    m = default_model()
    h = m.cfg.params
    bad = {"hydraulics.mu": h["hydraulics.mu"].range[0], "hydraulics.k_a2": h["hydraulics.k_a2"].range[1],
           "hydraulics.k_a_report": h["hydraulics.k_a_report"].range[0],
           "hydraulics.k_s": h["hydraulics.k_s"].range[1]}
    kp, ki = m.gains("kp1")
    assert np.max(np.linalg.eigvals(position_loop(perturbed_rate_loop(m, bad), kp, ki).A).real) > 0
    assert np.max(np.linalg.eigvals(position_loop(perturbed_rate_loop(m, {}), kp, ki).A).real) < 0


# ------------------------------------------------------------------ poles, sensitivity, wind
def test_rate_loop_poles_below_1hz(run: dict) -> None:
    """Each pole sits in one channel (residue 100x the other's); the rigid-structure table
    holds the az drive's well-damped pair and el's real poles; the model's poles are stable."""
    poles = run["data"]["rate_loop_poles"]
    for which in ("model", "rigid_structure"):
        rows = poles[which]
        assert {r["channel"] for r in rows} == {"az", "el"}, which
        for r in rows:
            assert r["freq_hz"] < 1.0 and r["re"] < 0 and r["dominance"] > 100, (which, r)
            assert (r["kind"] == "real") == (r["zeta"] == pytest.approx(1.0)), (which, r)


def test_rate_loop_phase_lag_az_larger_than_el(metrics: dict) -> None:
    """Fig. 17 drawn with phase: the az rate loop lags more at 0.3 Hz (its complex poles near
    0.5 Hz) than el (a real pole near 0.35 Hz)."""
    az, el = val(metrics, "rate_loop_phase_deg_0p3hz_az"), val(metrics, "rate_loop_phase_deg_0p3hz_el")
    assert -90 < az < el < 0


@pytest.mark.slow
def test_viscosity_sensitivity_matches_the_committed_results() -> None:
    """The ends of [R] Table 2's viscosity range and the nominal, each recalibrated (about
    10 s): more viscosity (less leakage, a stiffer drive) lowers the az kp 1 bandwidth, and
    the committed results file holds today's figures."""
    sens = rep.viscosity_sensitivity(default_model())
    rows = sens["rows"]
    assert [r["mu_kpas"] for r in rows] == pytest.approx([2.8e-4, 1.5e-3, 2.8e-3])
    assert [r["nominal"] for r in rows] == [False, True, False]
    bw = [r["values"]["pi_bandwidth_hz_az_kp1"] for r in rows]
    assert bw[0] > bw[1] > bw[2]
    committed = json.loads(RESULTS.read_text())["viscosity_sensitivity"]["rows"]
    for a, b in zip(committed, rows, strict=True):
        assert a["failed"] == b["failed"]
        assert a["lambda"] == pytest.approx(b["lambda"], rel=1e-4)
        for k in b["values"]:
            tol = dict(abs=0.025) if "settling" in k else dict(rel=1e-3, abs=1e-12)
            assert a["values"][k] == pytest.approx(b["values"][k], **tol), k


def test_wind_coefficients_beside_literature(run: dict) -> None:
    """The calibrated moment coefficients that the Table 4 fit needs lie in the ranges the public
    wind-load evidence accepts (docs/wind.md section 6: C_el front 0.032-0.22, central 0.12;
    C_az side 0.0103-0.074, central 0.045); the others have no public figure."""
    c = run["data"]["wind_loads"]["coefficients"]
    for key, central, (lo, hi) in (("el_front", 0.12, (0.032, 0.22)), ("az_side", 0.045, (0.0103, 0.074))):
        assert c[key]["evidence_nominal"] == pytest.approx(central), key
        assert c[key]["evidence_range"] == pytest.approx([lo, hi]), key
        assert lo <= c[key]["calibrated"] <= hi, key
    assert c["az_front"]["evidence_nominal"] is None and c["el_side"]["evidence_nominal"] is None


def test_wind_errors_follow_the_drive_compliance(run: dict) -> None:
    """docs/wind.md: with the coefficients held, the leakage term 3 k_a2 / mu sets the drive's
    compliance to load torque: doubling k_a2 about doubles it, halving halves it.  The gust
    errors rise with it: doubling k_a2 about doubles the 3-sigma errors.  On the stiff shipped
    drive a part of the error that the drive compliance does not set remains when k_a2 is
    halved (about 0.56x el front, 0.65x az side), so halving lowers the errors by less than half.
    """
    rows = {r["k_a2_factor"]: r for r in run["data"]["wind_loads"]["drive_sensitivity"]["rows"]}
    assert set(rows) == {0.5, 1.0, 2.0}
    for fac in (0.5, 2.0):
        for ax in AXES:
            c = rows[fac]["compliance_rad_s_per_Nm"][ax] / rows[1.0]["compliance_rad_s_per_Nm"][ax]
            assert c == pytest.approx(fac, rel=0.05), (fac, ax)
    for key in ("three_sigma_mdeg_el_front", "three_sigma_mdeg_az_side"):
        assert rows[2.0][key] / rows[1.0][key] == pytest.approx(2.0, rel=0.15), key
        assert 0.5 < rows[0.5][key] / rows[1.0][key] < 1.0, key


# ------------------------------------------------------------------ the committed results file


def test_committed_results_match_the_code(run: dict) -> None:
    """docs/results/reproduce_metrics.json (the source of the README's and docs' tables) is
    what the code gives today.  Refresh it with ``dss14 reproduce --no-figures --out DIR`` and
    copy ``DIR/metrics.json`` there, then run ``scripts/render_reproduce_tables.py``."""
    committed = json.loads(RESULTS.read_text())
    fresh = run["data"]
    assert set(committed["metrics"]) == set(fresh["metrics"])
    for k, row in fresh["metrics"].items():
        old = committed["metrics"][k]
        tol = dict(abs=0.025) if "settling" in k else dict(rel=1e-3, abs=1e-12)
        assert old["model"] == pytest.approx(row["model"], **tol), k
        assert old["accepted"] == row["accepted"] and old["ok"] == row["ok"], k
    for which in ("model", "rigid_structure"):
        a, b = committed["rate_loop_poles"][which], fresh["rate_loop_poles"][which]
        assert [(r["channel"], r["kind"]) for r in a] == [(r["channel"], r["kind"]) for r in b]
        assert [r["freq_hz"] for r in a] == pytest.approx([r["freq_hz"] for r in b], rel=1e-4)
        assert [r["zeta"] for r in a] == pytest.approx([r["zeta"] for r in b], rel=1e-4)
    nominal = [r for r in committed["viscosity_sensitivity"]["rows"] if r["nominal"]]
    assert nominal[0]["values"] == {k: v["model"] for k, v in committed["metrics"].items()
                                    if k in nominal[0]["values"]}
    for k, c in fresh["wind_loads"]["coefficients"].items():
        assert committed["wind_loads"]["coefficients"][k]["calibrated"] == pytest.approx(c["calibrated"],
                                                                                          rel=1e-4), k
    assert committed["config"] == "configs/model.yaml (shipped)"


@pytest.mark.slow
def test_config_whose_wind_refit_misses_table4_writes_everything_and_exits_1(tmp_path: Path, capsys,
                                                                             monkeypatch) -> None:
    """mu 2.8e-3 kPa*s with k_a2 4.1e-4 cm^3 (both at their range ends): the wind fit bounded by the
    evidence's ranges cannot meet Table 4's az-in-front-wind range on so stiff a drive (its el
    front load moves the az encoder); the fit is written, its rows fail."""
    text = default_config_path().read_text()
    old, new = "mu:       {value: 1.5e-3,", "mu:       {value: 2.8e-3,"
    assert old in text and "k_a2:     {value: 4.1e-4," in text
    text = text.replace(old, new)
    cfg = tmp_path / "stiff.yaml"
    cfg.write_text(text)
    monkeypatch.setattr(rep, "SENSITIVITY_MU_KPAS", ())
    rc = main(["reproduce", "--out", str(tmp_path / "out"), "--config", str(cfg), "--no-figures"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "wind_3sigma_mdeg_az_front_lyap" in err
    data = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert data["metrics"]["wind_3sigma_mdeg_az_front_lyap"]["ok"] is False
    missed = data["wind_loads"]["table4_missed"]
    assert any("az front" in m for m in missed), missed
    assert (tmp_path / "out" / "metrics.md").is_file()
