"""Board, hydraulics, gearbox and drive blocks against the report's equations.

Expected values are the report's printed numbers ([R] Eqs. 4-9, 33), its matrices (Eqs. 34b,
37b) written out here from the block parameters, and a hand solution of the Fig. 1 loop
equations; nothing is taken from the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from dss14_env.model.assembly import DSS14Model, default_model
from dss14_env.model.board import board_dc_gains, board_ss
from dss14_env.model.drive import DriveParams, drive_by_interconnection, drive_ss
from dss14_env.model.gearbox import gearbox_ss
from dss14_env.model.hydraulics import HydraulicParams, hydraulics_ss
from dss14_env.model.linsys import freqresp

AXES = ["az", "el"]

# [R] printed numbers
K_R, K_T, G_R1, G_R2, G_S = 1212.6, 2.5, 6.20, -4.65, 4.42e-5  # text after Eq. (5), Eqs. (3), (5)
G_TO = {"az": 0.151, "el": 0.127}  # Eqs. (1), (2)
TAU_Z, TAU_P = 0.400, 4.205  # Eq. (4)
GR_REPORT = 0.3323  # Eq. (6)
GT_REPORT = {"az": -0.7750e-4, "el": -0.6525e-4}  # Eq. (8)
N_O = {"az": 4287.5, "el": 5083.6}  # text before Eq. (9)

FREQS_HZ = np.array([1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 8.0, 20.0, 50.0, 100.0])


@pytest.fixture(scope="module")
def model() -> DSS14Model:
    return default_model()


def _g_o(s: complex) -> complex:
    """Lag compensator G_o of Eq. (4)."""
    return (1 + TAU_Z * s) / (1 + TAU_P * s)


def _rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b) / np.abs(b)))


# ------------------------------------------------------------------ board, Eqs. (1)-(10)
def test_report_board_numbers_consistent() -> None:
    """The report's own products reproduce its printed Eq. (6) and Eq. (8) gains."""
    assert K_R * G_R1 * G_S == pytest.approx(GR_REPORT, rel=5e-3)
    for ax in AXES:
        assert K_T * G_TO[ax] * G_R2 * G_S == pytest.approx(GT_REPORT[ax], rel=5e-3)


@pytest.mark.parametrize("axis", AXES)
def test_board_dc_gains_vs_report(model: DSS14Model, axis: str) -> None:
    g_r, g_t = board_dc_gains(model.cfg, axis)
    assert g_r == pytest.approx(GR_REPORT, rel=5e-3)  # Eq. (6)
    assert g_t == pytest.approx(GT_REPORT[axis], rel=5e-3)  # Eq. (8)
    assert g_t < 0 < g_r


@pytest.mark.parametrize("axis", AXES)
def test_board_ratio_is_tach_to_axis_ratio(model: DSS14Model, axis: str) -> None:
    """Eq. (9): G_r/G_t = -N_o (the report gets -4287.7 / -5092.7)."""
    g_r, g_t = board_dc_gains(model.cfg, axis)
    assert g_r / g_t == pytest.approx(-N_O[axis], rel=5e-3)


@pytest.mark.parametrize("axis", AXES)
def test_board_ss_frequency_response(model: DSS14Model, axis: str) -> None:
    b = board_ss(model.cfg, axis)
    assert b.nstates == 1
    s = 2j * np.pi * FREQS_HZ
    go = np.array([_g_o(x) for x in s])
    g_r0 = K_R * G_R1 * G_S
    g_t0 = K_T * G_TO[axis] * G_R2 * G_S
    assert _rel_err(freqresp(b, FREQS_HZ, "i", "r"), g_r0 * go) < 1e-9
    assert _rel_err(freqresp(b, FREQS_HZ, "i", "tach_rate"), g_t0 * go) < 1e-9
    # and the printed rounded gain 0.3323 within its rounding
    assert _rel_err(freqresp(b, FREQS_HZ, "i", "r"), GR_REPORT * go) < 1e-5


@pytest.mark.parametrize("axis", AXES)
def test_board_ss_pole_is_lag_pole(model: DSS14Model, axis: str) -> None:
    poles = np.linalg.eigvals(board_ss(model.cfg, axis).A)
    assert poles == pytest.approx([-1.0 / TAU_P], rel=1e-12)


# ------------------------------------------------------------------ hydraulics, Eq. (34)
def _hyd(model: DSS14Model, axis: str) -> HydraulicParams:
    return model.drive_params(axis).hydraulics


@pytest.mark.parametrize("axis", AXES)
def test_hydraulic_params_from_config(model: DSS14Model, axis: str) -> None:
    p, h = _hyd(model, axis), model.cfg.hydraulics
    assert (p.zeta_o, p.omega_o, p.k_s, p.k_p, p.k_a2, p.mu, p.d, p.k_v, p.beta) == (
        h.zeta_o, h.omega_o, h.k_s, h.k_p, h.k_a2, h.mu, h.d_motor, h.k_v, h.beta)
    assert p.v_o == h.v_o[axis]
    assert p.k_a > 0


def test_line_gain_az_vs_report(model: DSS14Model) -> None:
    """Eq. (33): k_l = beta / v_o = 47.3 kPa/cm^3 (az, printed) = 4.73e10 Pa/m^3."""
    p = _hyd(model, "az")
    assert p.k_l == pytest.approx(47.3e3 / 1e-6, rel=5e-3)
    assert p.k_l == pytest.approx(1.29e9 / 0.0272, rel=1e-12)


@pytest.mark.parametrize("axis", AXES)
def test_hydraulics_matrices_eq34b(model: DSS14Model, axis: str) -> None:
    p = _hyd(model, axis)
    w, z, D = p.omega_o, p.zeta_o, p.d
    kl = p.beta / p.v_o  # Eq. (33)
    c = 3 * p.k_a2 / p.mu + 2 * p.k_p + 2 * p.k_s
    A = np.array([[-2 * z * w, -w ** 2, 0.0], [1.0, 0.0, 0.0], [0.0, kl, kl * -c]])
    B_hi = np.array([[2 * w ** 2 * p.k_a], [0.0], [0.0]])
    B_ho = np.array([[0.0], [0.0], [-2 * kl * D]])
    C_h = np.array([[0.0, 0.0, D]])
    D_hi, D_ho = 0.0, -p.k_v * D * p.mu
    h = hydraulics_ss(p, axis)
    assert h.input_labels == ["i", "motor_rate"] and h.output_labels == ["T_o"]
    np.testing.assert_allclose(h.A, A, rtol=1e-12, atol=0)
    np.testing.assert_allclose(h.B, np.hstack([B_hi, B_ho]), rtol=1e-12, atol=0)
    np.testing.assert_allclose(h.C, C_h, rtol=1e-12, atol=0)
    np.testing.assert_allclose(h.D, [[D_hi, D_ho]], rtol=1e-12, atol=0)


@pytest.mark.parametrize("axis", AXES)
def test_hydraulics_poles(model: DSS14Model, axis: str) -> None:
    p = _hyd(model, axis)
    poles = np.sort_complex(np.linalg.eigvals(hydraulics_ss(p, axis).A))
    valve = np.roots([1.0, 2 * p.zeta_o * p.omega_o, p.omega_o ** 2])
    pressure = -(p.beta / p.v_o) * (3 * p.k_a2 / p.mu + 2 * p.k_p + 2 * p.k_s)
    expected = np.sort_complex(np.concatenate([valve, [pressure]]))
    np.testing.assert_allclose(poles, expected, rtol=1e-9)
    # the valve pair: natural frequency omega_o, damping zeta_o
    vp = poles[np.abs(poles - pressure) > 1e-6 * abs(pressure)]
    assert vp.size == 2
    assert np.abs(vp) == pytest.approx([345.56, 345.56], rel=1e-9)
    assert -vp.real / np.abs(vp) == pytest.approx([0.8, 0.8], rel=1e-9)


# ------------------------------------------------------------------ gearbox, Eq. (37)
@pytest.mark.parametrize("axis", AXES)
def test_gearbox_matrices_eq37b(model: DSS14Model, axis: str) -> None:
    g = model.drive_params(axis).gearbox
    N, J, kg = g.n, g.j_m, g.k_g
    gs = gearbox_ss(g, axis)
    np.testing.assert_allclose(gs.A, [[0.0, -1.0 / (N * J)], [kg / N, 0.0]], rtol=1e-12, atol=0)
    np.testing.assert_allclose(gs.B, [[1.0 / J, 0.0], [0.0, -kg]], rtol=1e-12, atol=0)
    np.testing.assert_allclose(gs.C, [[0.0, 1.0], [1.0, 0.0]], rtol=0, atol=0)  # C_g1; C_g2
    np.testing.assert_array_equal(gs.D, np.zeros((2, 2)))
    assert gs.output_labels == ["T", "motor_rate"]
    assert gs.input_labels == ["T_o", "pinion_rate"]


@pytest.mark.parametrize("axis", AXES)
def test_gearbox_eigenvalues(model: DSS14Model, axis: str) -> None:
    g = model.drive_params(axis).gearbox
    w = np.sqrt(g.k_g / (g.n ** 2 * g.j_m))
    ev = np.sort_complex(np.linalg.eigvals(gearbox_ss(g, axis).A))
    np.testing.assert_allclose(ev.real, [0.0, 0.0], atol=1e-9 * w)
    np.testing.assert_allclose(ev.imag, [-w, w], rtol=1e-12)


# ------------------------------------------------------------------ drive, Eq. (38)
@pytest.mark.parametrize("axis", AXES)
def test_drive_eq38_vs_interconnection(model: DSS14Model, axis: str) -> None:
    p = model.drive_params(axis)
    d1, d2 = drive_ss(p), drive_by_interconnection(p)
    assert d1.nstates == 6
    for out in ("T", "motor_rate"):
        for inp in ("r", "pinion_rate"):
            h1 = freqresp(d1, FREQS_HZ, out, inp)
            h2 = freqresp(d2, FREQS_HZ, out, inp)
            assert _rel_err(h1, h2) <= 1e-9, (out, inp)


def _hand_drive(p: DriveParams, s: complex) -> dict[str, complex]:
    """Fig. 1 loop equations solved by hand at one s.

    i = G_r r + G_t w_m / N_t;  q_v = 2 w^2 k_a i / (s^2 + 2 z w s + w^2);
    p = k_l (q_v - 2 D w_m) / (s + k_l c);  T_o = D p - k_v D mu w_m;
    J_m s w_m = T_o - T / N;  s T = k_g (w_m / N - pinion_rate).
    """
    h, g = p.hydraulics, p.gearbox
    G_o = _g_o(s)  # board gains from the printed Eqs. (4)-(7), not from p.board
    gr = K_R * G_R1 * G_S * G_o
    gt = K_T * G_TO[p.axis] * G_R2 * G_S * G_o
    w, z = h.omega_o, h.zeta_o
    kl = h.beta / h.v_o
    c = 3 * h.k_a2 / h.mu + 2 * h.k_p + 2 * h.k_s
    hv = 2 * w ** 2 * h.k_a / (s ** 2 + 2 * z * w * s + w ** 2)
    # T_o = P_i i - P_w w_m
    P_i = h.d * kl * hv / (s + kl * c)
    P_w = 2 * h.d ** 2 * kl / (s + kl * c) + h.k_v * h.d * h.mu
    N, J, kg, Nt = g.n, g.j_m, g.k_g, p.n_t
    Z = J * s + P_w - P_i * gt / Nt  # motor-side impedance with the tach loop closed
    # r input, pinion_rate = 0: J s w_m = P_i (gr r + gt w_m/Nt) - P_w w_m - kg w_m/(N^2 s)
    wm_r = P_i * gr / (Z + kg / (N ** 2 * s))
    T_r = kg / (N * s) * wm_r
    # pinion_rate input, r = 0: Z w_m = -T/N,  s T = kg (w_m/N - theta_p)
    T_p = -kg / (s + kg / (N ** 2 * Z))
    wm_p = -T_p / (N * Z)
    return {"T/r": T_r, "motor_rate/r": wm_r, "T/pinion_rate": T_p,
            "motor_rate/pinion_rate": wm_p}


@pytest.mark.parametrize("axis", AXES)
def test_drive_vs_hand_solution_of_fig1(model: DSS14Model, axis: str) -> None:
    p = model.drive_params(axis)
    d = drive_ss(p)
    hand = [_hand_drive(p, 2j * np.pi * f) for f in FREQS_HZ]
    for key in ("T/r", "motor_rate/r", "T/pinion_rate", "motor_rate/pinion_rate"):
        out, inp = key.split("/")
        expected = np.array([h[key] for h in hand])
        assert _rel_err(freqresp(d, FREQS_HZ, out, inp), expected) <= 1e-9, key


# ------------------------------------------------------------------ rate loop DC
def _dc(model: DSS14Model, axis: str, output: str) -> float:
    """Exact DC gain of the rate loop, r -> output, with the rigid-body angle states removed
    (they only integrate the rate and feed nothing back)."""
    rl = model.rate_loop
    drop = [rl.state_labels.index(q) for q in ("q0", "q1")]
    assert np.all(rl.A[:, drop] == 0.0)
    keep = [i for i in range(rl.nstates) if i not in drop]
    A = rl.A[np.ix_(keep, keep)]
    inp = rl.input_labels.index("r_a" if axis == "az" else "r_e")
    out = rl.output_labels.index(output)
    x = np.linalg.solve(A, -rl.B[keep, inp])
    return float(rl.C[out, keep] @ x + rl.D[out, inp])


@pytest.mark.parametrize("axis", AXES)
def test_rate_loop_dc_closed_form(model: DSS14Model, axis: str) -> None:
    """DC of r -> encoder rate with a free rigid load: kappa lam / (1 + lam) (docs/model.md
    section 7); the neglected viscous-friction term is about 2e-6 of 2 D, hence 1e-6."""
    cal = model.calibration
    lam, kappa = cal.lam[axis], cal.kappa[axis]
    expected = kappa * lam / (1 + lam)
    dc = _dc(model, axis, f"enc_rate_{axis}")
    assert dc == pytest.approx(expected, rel=1e-6)
    # the low-frequency response agrees with the exact DC (1e-5 Hz: far below the 0.038 Hz
    # lag pole of the board)
    inp = "r_a" if axis == "az" else "r_e"
    h = freqresp(model.rate_loop, [1e-5], f"enc_rate_{axis}", inp)[0]
    assert abs(h) == pytest.approx(dc, rel=1e-6)


@pytest.mark.parametrize("axis", AXES)
def test_rate_loop_dc_steady_state_by_hand(model: DSS14Model, axis: str) -> None:
    """Steady state with a free load (T = 0) from the Fig. 1 equations at s = 0:
    T_o = 0 -> p = k_v mu w_m; q_v = 2 D w_m + c p = 2 k_a i; i = G_r r + G_t w_m / N_t;
    axis rate = w_m / (N N_p)."""
    p = model.drive_params(axis)
    h = p.hydraulics
    c = 3 * h.k_a2 / h.mu + 2 * h.k_p + 2 * h.k_s
    gr, gt = K_R * G_R1 * G_S, K_T * G_TO[axis] * G_R2 * G_S
    wm = 2 * h.k_a * gr / (2 * h.d + c * h.k_v * h.mu - 2 * h.k_a * gt / p.n_t)
    expected = wm / (p.gearbox.n * p.n_p)
    assert _dc(model, axis, f"enc_rate_{axis}") == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("axis", AXES)
def test_rate_command_gear_train(model: DSS14Model, axis: str) -> None:
    """1 axis rad/s commanded: in steady state the motor turns N N_p times the axis rate, the
    pinion N_p times, and the axis at DC x 1 rad/s."""
    p = model.drive_params(axis)
    dc = _dc(model, axis, f"enc_rate_{axis}")
    motor = _dc(model, axis, f"motor_rate_{axis}")
    pinion = _dc(model, axis, f"pinion_rate_{axis}")
    assert motor == pytest.approx(dc * p.gearbox.n * p.n_p, rel=1e-9)
    assert pinion == pytest.approx(dc * p.n_p, rel=1e-9)
    assert p.n_p == model.cfg.gearbox.n_p and p.n_t == model.cfg.gearbox.n_t
    # the calibrated kinematic factor: kappa = |G_r/G_t| N_t / (N N_p)
    gr, gt = K_R * G_R1 * G_S, K_T * G_TO[axis] * G_R2 * G_S
    kappa = abs(gr / gt) * p.n_t / (p.gearbox.n * p.n_p)
    assert kappa == pytest.approx(model.calibration.kappa[axis], rel=1e-9)
