"""Structure model ([R] Section III, Eqs. 39-55) and Fig. 15 features.

Expected values come from physics (rigid-body motion, inertia sums written out here from the
configuration's masses and geometry), the report (150 modes, 1 % damping, 2 + 22 modes kept,
1.2 / 2.2 Hz az resonances, none in el below 3 Hz) and independent numerics (scipy eigen
solvers and Lyapunov equations).  The 1.2 / 2.2 Hz az resonances are what the calibration's
first step solves for: the tests named ``test_regression_calibrated_*`` re-check them (a broken
calibration or reduction fails them); they are not evidence for the structure model.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from dss14_env.model.assembly import DSS14Model, default_model
from dss14_env.model.calibration import lumped_structure
from dss14_env.model.linsys import freqresp
from dss14_env.model.reduction import exact_mode_hsv, hankel_singular_values
from dss14_env.model.structure import STRUCT_INPUTS, STRUCT_OUTPUTS, LumpedStructure, ModalModel

AXES = ["az", "el"]
ZETA = 0.01  # [R] Section III: 1 % modal damping


@pytest.fixture(scope="module")
def model() -> DSS14Model:
    return default_model()


@pytest.fixture(scope="module")
def lumped(model: DSS14Model) -> LumpedStructure:
    c = model.calibration
    return lumped_structure(model.cfg, c.az_chain_scale, c.j_az_el)


@pytest.fixture(scope="module")
def full(model: DSS14Model) -> ModalModel:
    return model.structure_full


@pytest.fixture(scope="module")
def reduced(model: DSS14Model) -> ModalModel:
    return model.structure


# ------------------------------------------------------------------ helpers written out here
def _rigid_by_hand(ls: LumpedStructure, axis: str) -> np.ndarray:
    """Displacements of every DOF under a rigid rotation of 1 rad about the az or el axis:
    rotational DOFs of the rotating bodies move 1 rad, the contact node n1 moves R along the
    rail tangent (-cos a, sin a) (Eq. 52), rib nodes move axially by their lever arm
    (r cos(E) sin(phi) about az, r cos(phi) about el), quadripod and subreflector move laterally
    by h cos(E) (xel, az) or h (el)."""
    s = ls.cfg
    cE = np.cos(s.elevation_angle)
    q = np.zeros(len(ls.dofs))
    ribs = 2 * np.pi * np.arange(s.n_ribs) / s.n_ribs
    radii = np.linspace(s.rib_r_inner, s.rib_r_outer, s.n_rib_nodes)
    if axis == "az":
        rot = ["az.ring", "az.tip"] + [f"az.alidade{i + 1}" for i in range(len(s.j_alidade))]
        R, a, lat, f = s.r_rail_az, s.alpha_az, "v", cE
    else:
        rot = ["el.wheel", "el.tip", "el.cw"]
        R, a, lat, f = s.r_rail_el, s.alpha_el, "u", 1.0
    for name in rot:
        q[ls.dofs.index(name)] = 1.0
    q[ls.dofs.index(f"{axis}.n1x")] = -R * np.cos(a)
    q[ls.dofs.index(f"{axis}.n1y")] = R * np.sin(a)
    for j, phi in enumerate(ribs):
        for k, r in enumerate(radii):
            lever = r * cE * np.sin(phi) if axis == "az" else r * np.cos(phi)
            q[ls.dofs.index(f"rib{j}.{k}")] = lever
    q[ls.dofs.index(f"sub.{lat}")] = f * s.subreflector_height
    for leg in range(4):
        q[ls.dofs.index(f"leg{leg}.{lat}")] = f * s.quad_leg_height
    return q


def _j_axis_by_hand(model: DSS14Model, axis: str) -> float:
    """Rigid-body inertia about an axis, summed from the configuration's masses."""
    s = model.cfg.structure
    cE = np.cos(s.elevation_angle)
    phis = 2 * np.pi * np.arange(s.n_ribs) / s.n_ribs
    radii = np.linspace(s.rib_r_inner, s.rib_r_outer, s.n_rib_nodes)
    if axis == "az":
        j = s.j_ring + sum(s.j_alidade) + s.j_tip_az + s.m_node_az * s.r_rail_az ** 2
        j += sum(s.rib_node_mass * (r * cE * np.sin(phi)) ** 2 for phi in phis for r in radii)
        j += 4 * s.m_quad_node * (s.quad_leg_height * cE) ** 2
        j += s.m_subreflector * (s.subreflector_height * cE) ** 2
    else:
        j = s.j_wheel_el + s.j_tip_el + s.j_counterweight + s.m_node_el * s.r_rail_el ** 2
        j += sum(s.rib_node_mass * (r * np.cos(phi)) ** 2 for phi in phis for r in radii)
        j += 4 * s.m_quad_node * s.quad_leg_height ** 2
        j += s.m_subreflector * s.subreflector_height ** 2
    return float(j)


def _scales(model: DSS14Model) -> tuple[np.ndarray, np.ndarray]:
    """Unit-consistent Eq. (55) weights (docs/model.md section 5): pinion torques x N_p,
    pinion rates / N_p."""
    n_p = model.cfg.gearbox.n_p
    ins = np.array([n_p, n_p, 1.0, 1.0])
    outs = np.array([1.0 / n_p, 1.0 / n_p] + [1.0] * 6)
    assert STRUCT_INPUTS[:2] == ["T_a", "T_e"]
    assert STRUCT_OUTPUTS[:2] == ["pinion_rate_az", "pinion_rate_el"]
    return ins, outs


def _eq55(m: ModalModel, ins: np.ndarray, outs: np.ndarray) -> np.ndarray:
    """gamma_i = beta_i sqrt(alpha_q^2 + w^2 alpha_r^2) / (4 zeta w^2), unit weights."""
    beta = np.sqrt(np.sum((m.b * ins) ** 2, axis=1))
    aq = np.sqrt(np.sum((m.cq * outs[:, None]) ** 2, axis=0))
    ar = np.sqrt(np.sum((m.cv * outs[:, None]) ** 2, axis=0))
    g = np.full(m.n_modes, np.inf)
    for i in range(m.n_modes):
        if m.omega[i] > 0:
            w = m.omega[i]
            g[i] = beta[i] * np.sqrt(aq[i] ** 2 + (w * ar[i]) ** 2) / (4 * m.zeta[i] * w ** 2)
    return g


def _exact_hsv(m: ModalModel, i: int, ins: np.ndarray, outs: np.ndarray) -> float:
    """Largest Hankel singular value of mode i alone, from its gramians."""
    w, z = m.omega[i], m.zeta[i]
    A = np.array([[0.0, 1.0], [-w * w, -2 * z * w]])
    B = np.vstack([np.zeros(len(ins)), m.b[i] * ins])
    C = np.column_stack([m.cq[:, i] * outs, m.cv[:, i] * outs])
    P = scipy.linalg.solve_continuous_lyapunov(A, -B @ B.T)
    Q = scipy.linalg.solve_continuous_lyapunov(A.T, -C.T @ C)
    Lp = np.linalg.cholesky(P)
    Lq = np.linalg.cholesky(Q)
    return float(np.linalg.svd(Lq.T @ Lp, compute_uv=False)[0])


# ------------------------------------------------------------------ size and matrices
def test_150_dofs_and_modes(lumped: LumpedStructure, full: ModalModel) -> None:
    assert lumped.n_dof == 150
    assert lumped.M.shape == lumped.K.shape == (150, 150)
    assert full.n_modes == 150
    assert full.b.shape == (150, 4) and full.cq.shape == full.cv.shape == (8, 150)


def test_exactly_two_rigid_modes(full: ModalModel) -> None:
    zero = np.flatnonzero(full.omega == 0.0)
    assert list(zero) == [0, 1]
    assert tuple(full.rigid) == (0, 1)
    assert np.all(full.omega[2:] > 2 * np.pi * 0.5)


def test_mass_matrix_spd(lumped: LumpedStructure) -> None:
    M = lumped.M
    np.testing.assert_array_equal(M, M.T)
    ev = np.linalg.eigvalsh(M)
    assert ev.min() > 0


def test_stiffness_psd_two_null(lumped: LumpedStructure) -> None:
    K = lumped.K
    np.testing.assert_allclose(K, K.T, rtol=0, atol=1e-12 * np.abs(K).max())
    ev = np.linalg.eigvalsh(K)
    tol = 1e-9 * ev.max()
    assert ev.min() > -tol
    assert int(np.sum(np.abs(ev) < tol)) == 2
    assert ev[2] > 1e3 * tol  # a clear gap to the first elastic stiffness


@pytest.mark.parametrize("axis", AXES)
def test_rigid_rotation_is_null_vector(lumped: LumpedStructure, axis: str) -> None:
    q = _rigid_by_hand(lumped, axis)
    K = lumped.K
    assert np.linalg.norm(K @ q) <= 1e-12 * np.abs(K).max() * np.linalg.norm(q)
    # the package's rigid mode is the same vector
    np.testing.assert_allclose(lumped.rigid_mode(axis), q, rtol=1e-12, atol=1e-12)


def test_rigid_modes_of_modal_model(model: DSS14Model, full: ModalModel,
                                    lumped: LumpedStructure) -> None:
    """Modes 0 and 1 are the az and el rigid rotations: unit encoder angles, az modal mass =
    az inertia, and the torque input N_p / J_az (force T/r_a at lever R_a)."""
    enc_az, enc_el = STRUCT_OUTPUTS.index("enc_az"), STRUCT_OUTPUTS.index("enc_el")
    assert full.cq[enc_az, 0] == pytest.approx(1.0, rel=1e-12)
    assert full.cq[enc_el, 0] == pytest.approx(0.0, abs=1e-12)
    assert full.cq[enc_el, 1] == pytest.approx(1.0, rel=1e-12)
    q = _rigid_by_hand(lumped, "az")
    assert full.modal_mass[0] == pytest.approx(q @ lumped.M @ q, rel=1e-12)
    n_p = model.cfg.gearbox.n_p
    assert full.b[0, 0] == pytest.approx(n_p / _j_axis_by_hand(model, "az"), rel=1e-9)


def test_modal_frequencies_vs_eigh(lumped: LumpedStructure, full: ModalModel) -> None:
    w2 = scipy.linalg.eigh(lumped.K, lumped.M, eigvals_only=True)
    assert np.all(np.abs(w2[:2]) < 1e-9 * w2.max())
    np.testing.assert_allclose(np.sort(full.omega[2:]), np.sqrt(w2[2:]), rtol=1e-8)


def test_modal_frequencies_vs_cholesky_form(lumped: LumpedStructure, full: ModalModel) -> None:
    """Second independent route: eigenvalues of L^-1 K L^-T with M = L L^T."""
    L = np.linalg.cholesky(lumped.M)
    Li = scipy.linalg.solve_triangular(L, np.eye(L.shape[0]), lower=True)
    w2 = np.linalg.eigvalsh(Li @ lumped.K @ Li.T)
    np.testing.assert_allclose(np.sort(full.omega[2:]), np.sqrt(w2[2:]), rtol=1e-6)


def test_modal_damping(full: ModalModel, reduced: ModalModel) -> None:
    np.testing.assert_array_equal(full.zeta[2:], ZETA)
    np.testing.assert_array_equal(full.zeta[:2], 0.0)
    # poles of the reduced state-space model (Eq. 43): damping 1 % for every flexible pair
    poles = np.linalg.eigvals(reduced.to_ss().A)
    flex = poles[np.abs(poles) > 1e-6]
    assert flex.size == 2 * 22
    np.testing.assert_allclose(-flex.real / np.abs(flex), ZETA, rtol=1e-6)
    np.testing.assert_allclose(np.sort(np.abs(flex)), np.sort(np.repeat(reduced.omega[2:], 2)),
                               rtol=1e-8)


# ------------------------------------------------------------------ reduction, Eq. (55)
def test_reduced_model_24_modes(model: DSS14Model, full: ModalModel, reduced: ModalModel) -> None:
    assert reduced.n_modes == 24
    assert tuple(reduced.rigid) == (0, 1)
    assert int(np.sum(reduced.omega == 0.0)) == 2
    assert int(np.sum(reduced.omega > 0.0)) == 22
    assert np.all(np.diff(reduced.omega) >= 0)
    kept = np.asarray(model.kept_modes)
    np.testing.assert_array_equal(reduced.omega, full.omega[kept])
    np.testing.assert_array_equal(reduced.b, full.b[kept])
    np.testing.assert_array_equal(reduced.cv, full.cv[:, kept])
    assert reduced.to_ss().nstates == 48


def test_reduction_keeps_largest_hsv(model: DSS14Model, full: ModalModel) -> None:
    ins, outs = _scales(model)
    g = _eq55(full, ins, outs)
    kept = set(int(i) for i in model.kept_modes)
    assert {0, 1} <= kept
    flex_kept = sorted(kept - {0, 1})
    dropped = sorted(set(range(full.n_modes)) - kept)
    assert len(flex_kept) == 22
    assert min(g[flex_kept]) > max(g[dropped])
    top = set(int(i) for i in np.argsort(-g)[:24])
    assert top == kept
    # the package's Eq. (55) values agree with the ones written out here
    g_pkg = hankel_singular_values(full, input_scale=ins, output_scale=outs)
    finite = np.isfinite(g)
    assert np.all(np.isinf(g_pkg[~finite]))
    np.testing.assert_allclose(g_pkg[finite], g[finite], rtol=1e-10)


def test_eq55_vs_exact_hsv(model: DSS14Model, full: ModalModel) -> None:
    ins, outs = _scales(model)
    g = _eq55(full, ins, outs)
    checked = 0
    for i in sorted(int(k) for k in model.kept_modes):
        if i in full.rigid or full.omega[i] / (2 * np.pi) >= 30.0:
            continue
        exact = _exact_hsv(full, i, ins, outs)
        assert g[i] == pytest.approx(exact, rel=0.03), i
        assert exact_mode_hsv(full, i, input_scale=ins, output_scale=outs) == pytest.approx(
            exact, rel=1e-6), i
        checked += 1
    assert checked >= 15


# ------------------------------------------------------------------ rigid-body behaviour
def test_az_inertia_from_config(model: DSS14Model, full: ModalModel) -> None:
    j = _j_axis_by_hand(model, "az")
    assert full.modal_mass[0] == pytest.approx(j, rel=1e-9)
    assert 5e8 <= j <= 1e9  # assumed range of the az rotating inertia (docs/model.md section 5)


@pytest.mark.parametrize("f_hz", [1e-4, 3e-4])
def test_pinion_torque_to_az_rate_low_frequency(model: DSS14Model, reduced: ModalModel,
                                                f_hz: float) -> None:
    """Rigid body: J_az s theta' = N_p T_a (a force T/r_a at lever R_a = N_p r_a), corrected
    for the az-el product of inertia.

    The uncoupled value N_p / (J_az w) is off by the factor 1 / (1 - j^2 / (J_az J_el)); with the
    product of inertia recalibrated for Fig. 22 that factor exceeds 1e-3, so only the coupled
    value is asserted tightly.
    """
    n_p = model.cfg.gearbox.n_p
    j_az = _j_axis_by_hand(model, "az")
    h = freqresp(reduced.to_ss(), [f_hz], "enc_rate_az", "T_a")[0]
    assert np.angle(h) == pytest.approx(-np.pi / 2, abs=1e-3)  # an integrator
    # exact rigid-body value with the calibrated az-el product of inertia j:
    # [[J_az, j], [j, J_el]] s w = [N_p T, 0]
    j_el = _j_axis_by_hand(model, "el")
    jx = model.calibration.j_az_el
    exact = n_p * j_el / (j_az * j_el - jx ** 2) / (2 * np.pi * f_hz)
    assert abs(h) == pytest.approx(exact, rel=1e-5)


@pytest.mark.parametrize("f_hz", [1e-4, 1e-3])
def test_pinion_torque_to_el_rate_low_frequency(model: DSS14Model, reduced: ModalModel,
                                                f_hz: float) -> None:
    """Rigid body, el: [[J_az, j], [j, J_el]] s w = [0, N_p T_e] (as for az above)."""
    n_p = model.cfg.gearbox.n_p
    j_el = _j_axis_by_hand(model, "el")
    j_az = _j_axis_by_hand(model, "az")
    jx = model.calibration.j_az_el
    h = freqresp(reduced.to_ss(), [f_hz], "enc_rate_el", "T_e")[0]
    assert np.angle(h) == pytest.approx(-np.pi / 2, abs=1e-3)  # an integrator
    exact = n_p * j_az / (j_az * j_el - jx ** 2) / (2 * np.pi * f_hz)
    assert abs(h) == pytest.approx(exact, rel=1e-5)


# ------------------------------------------------------------------ Fig. 15
@pytest.fixture(scope="module")
def grid() -> np.ndarray:
    return np.geomspace(0.3, 3.0, 4000)


def _peaks(f: np.ndarray, mag: np.ndarray, prominence_db: float) -> np.ndarray:
    idx, props = scipy.signal.find_peaks(20 * np.log10(mag), prominence=prominence_db)
    order = np.argsort(-props["prominences"])
    return f[idx[order]]


def test_regression_calibrated_fig15_az_resonances_reduced_model(reduced: ModalModel,
                                                                  grid: np.ndarray) -> None:
    mag = np.abs(freqresp(reduced.to_ss(), grid, "enc_rate_az", "T_a"))
    peaks = _peaks(grid, mag, 3.0)
    assert peaks.size >= 2
    two = np.sort(peaks[:2])  # the two most prominent
    assert abs(two[0] - 1.2) <= 0.1
    assert abs(two[1] - 2.2) <= 0.1


def test_fig15_el_no_resonance_below_3hz(reduced: ModalModel, grid: np.ndarray) -> None:
    """Fig. 15(a) shows no el resonance below 3 Hz: no peak of more than 3 dB prominence (the
    definition the reproduce table uses, docs/model.md section 7).  The az-el product of inertia
    that Fig. 22's cross-coupling needs shows the 1.2 Hz az mode in el as a ripple of about 2.6 dB
    on the shipped drive, under that threshold (a stiffer drive would cross it, docs/model.md).
    """
    mag = np.abs(freqresp(reduced.to_ss(), grid, "enc_rate_el", "T_e"))
    assert _peaks(grid, mag, 3.0).size == 0


def test_regression_calibrated_fig15_az_resonances_full_model(full: ModalModel, grid: np.ndarray) -> None:
    """The 150-mode model the calibration works on has the Fig. 15 resonances (the reduced
    model's are checked above: the reduction keeps them)."""
    # modal superposition of Eq. (40), written out (the modal system is diagonal):
    # rate output  sum_i cv_i b_i s / (s^2 + 2 zeta_i w_i s + w_i^2)
    o, i = STRUCT_OUTPUTS.index("enc_rate_az"), STRUCT_INPUTS.index("T_a")
    s = 2j * np.pi * grid[:, None]
    w, z = full.omega[None, :], full.zeta[None, :]
    mag = np.abs(np.sum(full.cv[o] * full.b[:, i] * s / (s ** 2 + 2 * z * w * s + w ** 2), axis=1))
    two = np.sort(_peaks(grid, mag, 3.0)[:2])
    assert two.size == 2
    assert abs(two[0] - 1.2) <= 0.1 and abs(two[1] - 2.2) <= 0.1


def test_cross_coupling_weak(reduced: ModalModel) -> None:
    s = reduced.to_ss()
    direct = abs(freqresp(s, [0.05], "enc_rate_az", "T_a")[0])
    cross = abs(freqresp(s, [0.05], "enc_rate_el", "T_a")[0])
    assert 0 < cross / direct < 0.05


# ------------------------------------------------------------------ inputs and outputs
@pytest.mark.parametrize("axis", AXES)
def test_pinion_torque_input_eq47(lumped: LumpedStructure, model: DSS14Model, axis: str) -> None:
    s = model.cfg.structure
    R, a = (s.r_rail_az, s.alpha_az) if axis == "az" else (s.r_rail_el, s.alpha_el)
    r = R / model.cfg.gearbox.n_p  # pinion radius
    expected = np.zeros(lumped.n_dof)
    expected[lumped.dofs.index(f"{axis}.n1x")] = -np.cos(a) / r
    expected[lumped.dofs.index(f"{axis}.n1y")] = np.sin(a) / r
    col = STRUCT_INPUTS.index("T_a" if axis == "az" else "T_e")
    np.testing.assert_allclose(lumped.input_matrix()[:, col], expected, rtol=1e-12, atol=0)


@pytest.mark.parametrize("axis", AXES)
def test_rigid_rotation_outputs(lumped: LumpedStructure, model: DSS14Model, axis: str) -> None:
    Cq, Cv = lumped.output_matrices()
    q = _rigid_by_hand(lumped, axis)
    y = dict(zip(STRUCT_OUTPUTS, Cq @ q, strict=True))
    v = dict(zip(STRUCT_OUTPUTS, Cv @ q, strict=True))  # same vector read as a velocity of 1 rad/s
    other = "el" if axis == "az" else "az"
    n_p = model.cfg.gearbox.n_p
    assert y[f"enc_{axis}"] == pytest.approx(1.0, rel=1e-12)
    assert y[f"enc_{other}"] == pytest.approx(0.0, abs=1e-12)
    assert v[f"enc_rate_{axis}"] == pytest.approx(1.0, rel=1e-12)
    assert v[f"pinion_rate_{axis}"] == pytest.approx(n_p, rel=1e-12)  # Eq. (53a): R / r
    assert v[f"pinion_rate_{other}"] == pytest.approx(0.0, abs=1e-12)
    cE = np.cos(model.cfg.structure.elevation_angle)
    if axis == "el":
        assert y["point_el"] == pytest.approx(1.0, rel=1e-9)
        assert y["point_xel"] == pytest.approx(0.0, abs=1e-9)
    else:
        assert y["point_xel"] == pytest.approx(cE, rel=1e-9)
        assert y["point_el"] == pytest.approx(0.0, abs=1e-9)
