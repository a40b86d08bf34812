"""Antenna structure, [R] Section III, Eqs. (39)-(54).

The report's finite-element data are not public.  This module builds an FE-like model from a
lumped-parameter description of the antenna (``configs/model.yaml``, section ``structure``;
docs/model.md section 5): masses and inertias on springs, assembled into ``M`` and ``K``, whose
generalised eigenproblem gives the modal data the report starts from (natural frequencies,
mode shapes Phi, modal masses M_m; Eq. 39).  150 degrees of freedom give 150 modes: two
rigid-body modes (free azimuth and elevation rotation) and 148 flexible ones.

Degrees of freedom (translations in m, rotations in rad)

* azimuth: contact node n1 of the az pinion on the bull gear (x, y; Fig. 13), bull-gear ring
  (the az encoder is geared to it), alidade levels, tipping structure about the az axis;
* elevation: contact node n1 of the el pinion (x, y), elevation wheel (el encoder),
  tipping hub about the el axis, counterweight;
* dish: ``n_ribs`` radial ribs of ``n_rib_nodes`` point masses moving along the boresight,
  joined by shear springs along each rib and hoop springs between ribs;
* quadripod: four legs (lateral mid-node displacements, el and xel directions) and the
  subreflector apex (lateral el, xel).

Every spring is written on deformations *relative to the rigid-body motion*, so both rigid
modes are exact null vectors of ``K`` (tested).  The az-el coupling is the el drive's lever
(``el_drive_lever``): an az twist between alidade top and tipping structure moves the el
pinion contact point; the main az-el coupling is a product of inertia ``j_az_el`` of the tipping
structure (an asymmetric mass distribution), calibrated to the report's Fig. 22.

Inputs (the report's ``u_s``, Eq. 44, plus wind loads): pinion torques ``T_a``, ``T_e``
(N*m; Eqs. 45-50: a force ``T/r`` tangential at node n1) and wind torques ``Tw_az``,
``Tw_el`` (N*m about the axes, distributed over the rib nodes as a linear pressure pattern).
Outputs: pinion rates (Eqs. 51-53), encoder angles and rates at the drives, and the
elevation and cross-elevation pointing of the beam (best-fit dish tilt plus a subreflector
shift term).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import control as ct
import numpy as np
import scipy.linalg

from dss14_env.model.config import StructureConfig
from dss14_env.model.linsys import ss

STRUCT_INPUTS = ["T_a", "T_e", "Tw_az", "Tw_el"]
STRUCT_OUTPUTS = ["pinion_rate_az", "pinion_rate_el", "enc_az", "enc_el", "enc_rate_az",
                  "enc_rate_el", "point_el", "point_xel"]


@dataclass
class LumpedStructure:
    """Mass and stiffness matrices with input/output maps of the lumped antenna.

    :param cfg: the ``structure`` section of the configuration
    :param n_p: pinion-to-axis ratios ``{"az": .., "el": ..}`` (pinion radius = rail radius / n_p)
    """

    cfg: StructureConfig
    n_p: dict
    j_az_el: float = 0.0  # product of inertia of the tipping structure (az, el), kg*m^2

    def __post_init__(self) -> None:
        c = self.cfg
        self.dofs: list[str] = []
        self.mass: list[float] = []
        self.springs: list[tuple[float, dict[str, float]]] = []
        add = self._dof
        cE, phis = np.cos(c.elevation_angle), self.rib_angles
        # --- azimuth -------------------------------------------------------------------
        add("az.n1x", c.m_node_az)
        add("az.n1y", c.m_node_az)
        add("az.ring", c.j_ring)
        levels = [f"az.alidade{i + 1}" for i in range(len(c.j_alidade))]
        for name, j in zip(levels, c.j_alidade, strict=True):
            add(name, j)
        add("az.tip", c.j_tip_az)
        ta, na = self.tangent("az"), self.normal("az")
        self._spring(c.k_mesh_az, {"az.n1x": ta[0], "az.n1y": ta[1], "az.ring": -c.r_rail_az})
        self._spring(c.k_radial_az, {"az.n1x": na[0], "az.n1y": na[1]})
        chain = ["az.ring"] + levels + ["az.tip"]
        for k, (a, b) in zip(c.k_az_chain, zip(chain[:-1], chain[1:], strict=True), strict=True):
            self._spring(k, {b: 1.0, a: -1.0})
        # --- elevation -----------------------------------------------------------------
        add("el.n1x", c.m_node_el)
        add("el.n1y", c.m_node_el)
        add("el.wheel", c.j_wheel_el)
        add("el.tip", c.j_tip_el)
        add("el.cw", c.j_counterweight)
        te, ne = self.tangent("el"), self.normal("el")
        self._spring(c.k_mesh_el, {"el.n1x": te[0], "el.n1y": te[1], "el.wheel": -c.r_rail_el,
                                   levels[-1]: -c.el_drive_lever, "az.tip": c.el_drive_lever})
        self._spring(c.k_radial_el, {"el.n1x": ne[0], "el.n1y": ne[1]})
        self._spring(c.k_wheel_el, {"el.tip": 1.0, "el.wheel": -1.0})
        self._spring(c.k_counterweight, {"el.cw": 1.0, "el.tip": -1.0})
        # --- dish ribs: axial displacement w, deformation relative to the rigid hub --------
        for j in range(len(phis)):
            for k in range(len(self.rib_radii)):
                add(f"rib{j}.{k}", c.rib_node_mass)

        def rel(j: int, k: int) -> dict[str, float]:
            r, phi = self.rib_radii[k], phis[j]
            return {f"rib{j}.{k}": 1.0, "el.tip": -r * np.cos(phi), "az.tip": -r * cE * np.sin(phi)}

        nr = len(phis)
        for j in range(nr):
            for k in range(len(self.rib_radii)):
                self._spring(c.k_rib, rel(j, k) if k == 0 else _sub(rel(j, k), rel(j, k - 1)))
                self._spring(c.k_hoop, _sub(rel(j, k), rel((j + 1) % nr, k)))
        # --- quadripod legs and subreflector (lateral el 'u' and xel 'v') ----------------
        hq, hs = c.quad_leg_height, c.subreflector_height

        def lat(name: str, h: float, d: str) -> dict[str, float]:
            return {name: 1.0, "el.tip": -h} if d == "u" else {name: 1.0, "az.tip": -h * cE}

        for d in ("u", "v"):
            add(f"sub.{d}", c.m_subreflector)
        for leg in range(4):
            for d in ("u", "v"):
                node = f"leg{leg}.{d}"
                add(node, c.m_quad_node)
                self._spring(c.k_quad, lat(node, hq, d))
                self._spring(c.k_quad, _sub(lat(f"sub.{d}", hs, d), lat(node, hq, d)))

    # ------------------------------------------------------------------ geometry helpers
    @property
    def rib_angles(self) -> np.ndarray:
        return 2 * np.pi * np.arange(self.cfg.n_ribs) / self.cfg.n_ribs

    @property
    def rib_radii(self) -> np.ndarray:
        return np.linspace(self.cfg.rib_r_inner, self.cfg.rib_r_outer, self.cfg.n_rib_nodes)

    def tangent(self, axis: str) -> np.ndarray:
        """Unit tangent at the contact node, Eq. (52): ``v = -v_x cos(alpha) + v_y sin(alpha)``."""
        a = self.cfg.alpha_az if axis == "az" else self.cfg.alpha_el
        return np.array([-np.cos(a), np.sin(a)])

    def normal(self, axis: str) -> np.ndarray:
        a = self.cfg.alpha_az if axis == "az" else self.cfg.alpha_el
        return np.array([np.sin(a), np.cos(a)])

    def pinion_radius(self, axis: str) -> float:
        rail = self.cfg.r_rail_az if axis == "az" else self.cfg.r_rail_el
        return rail / self.n_p[axis]

    def _dof(self, name: str, m: float) -> None:
        self.dofs.append(name)
        self.mass.append(m)

    def _spring(self, k: float, coeffs: dict[str, float]) -> None:
        self.springs.append((k, coeffs))

    def e(self, name: str) -> np.ndarray:
        """Unit vector of one degree of freedom (the report's e_x, e_y)."""
        v = np.zeros(self.n_dof)
        v[self.dofs.index(name)] = 1.0
        return v

    # ------------------------------------------------------------------ matrices
    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    @cached_property
    def M(self) -> np.ndarray:
        M = np.diag(self.mass)
        i, j = self.dofs.index("az.tip"), self.dofs.index("el.tip")
        if self.j_az_el ** 2 >= M[i, i] * M[j, j]:
            raise ValueError("product of inertia j_az_el makes the mass matrix indefinite")
        M[i, j] = M[j, i] = self.j_az_el
        return M

    @cached_property
    def K(self) -> np.ndarray:
        K = np.zeros((self.n_dof, self.n_dof))
        idx = {n: i for i, n in enumerate(self.dofs)}
        for k, coeffs in self.springs:
            a = np.zeros(self.n_dof)
            for name, v in coeffs.items():
                a[idx[name]] += v
            K += k * np.outer(a, a)
        return K

    def rigid_mode(self, axis: str) -> np.ndarray:
        """Rigid rotation of 1 rad about the az or el axis, as a displacement vector."""
        c, cE = self.cfg, np.cos(self.cfg.elevation_angle)
        q = np.zeros(self.n_dof)
        idx = {n: i for i, n in enumerate(self.dofs)}
        if axis == "az":
            for n in self.dofs:
                if n in ("az.ring", "az.tip") or n.startswith("az.alidade"):
                    q[idx[n]] = 1.0
            q[idx["az.n1x"]], q[idx["az.n1y"]] = c.r_rail_az * self.tangent("az")
            geo = lambda r, phi: r * cE * np.sin(phi)  # noqa: E731
            lat = {"v": cE}
        else:
            for n in ("el.wheel", "el.tip", "el.cw"):
                q[idx[n]] = 1.0
            q[idx["el.n1x"]], q[idx["el.n1y"]] = c.r_rail_el * self.tangent("el")
            geo = lambda r, phi: r * np.cos(phi)  # noqa: E731
            lat = {"u": 1.0}
        for j, phi in enumerate(self.rib_angles):
            for k, r in enumerate(self.rib_radii):
                q[idx[f"rib{j}.{k}"]] = geo(r, phi)
        for d, f in lat.items():
            q[idx[f"sub.{d}"]] = f * c.subreflector_height
            for leg in range(4):
                q[idx[f"leg{leg}.{d}"]] = f * c.quad_leg_height
        return q

    # ------------------------------------------------------------------ inputs, outputs
    def input_matrix(self) -> np.ndarray:
        """B_o (n_dof x 4) for ``T_a, T_e, Tw_az, Tw_el``: Eq. (47) for the pinion torques."""
        cols = [self.tangent(ax)[0] * self.e(f"{ax}.n1x") / self.pinion_radius(ax)
                + self.tangent(ax)[1] * self.e(f"{ax}.n1y") / self.pinion_radius(ax)
                for ax in ("az", "el")]
        for ax in ("az", "el"):  # wind: forces on rib nodes proportional to the rigid lever
            lever = self._rib_only(self.rigid_mode(ax))
            cols.append(lever / (lever @ lever))
        return np.column_stack(cols)

    def _rib_only(self, q: np.ndarray) -> np.ndarray:
        mask = np.array([n.startswith("rib") for n in self.dofs])
        return np.where(mask, q, 0.0)

    def output_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(C_oq, C_ov), each (8 x n_dof), rows as :data:`STRUCT_OUTPUTS`."""
        n = self.n_dof
        Cq, Cv = np.zeros((len(STRUCT_OUTPUTS), n)), np.zeros((len(STRUCT_OUTPUTS), n))
        for row, ax in enumerate(("az", "el")):  # Eq. (53a): pinion rate = v_a / r_a
            t = self.tangent(ax)
            Cv[row] = (t[0] * self.e(f"{ax}.n1x") + t[1] * self.e(f"{ax}.n1y")) / self.pinion_radius(ax)
        Cq[2], Cq[3] = self.e("az.ring"), self.e("el.wheel")  # encoders at the drives
        Cv[4], Cv[5] = self.e("az.ring"), self.e("el.wheel")
        c = self.cfg
        g, hs = c.subreflector_pointing_factor, c.subreflector_height
        for row, ax, d in ((6, "el", "u"), (7, "az", "v")):
            lever = self._rib_only(self.rigid_mode(ax))
            scale = 1.0 if ax == "el" else np.cos(c.elevation_angle)
            tilt = lever / (lever @ lever) * scale  # best-fit dish tilt (xel = cos(E) * az)
            sub = self.e(f"sub.{d}") / hs - tilt  # subreflector shift relative to the dish axis
            Cq[row] = tilt + g * sub
        return Cq, Cv


def _sub(a: dict[str, float], b: dict[str, float]) -> dict[str, float]:
    out = dict(a)
    for k, v in b.items():
        out[k] = out.get(k, 0.0) - v
    return out


@dataclass(frozen=True)
class ModalModel:
    """Modal data of Eq. (39)-(40) with the structure's inputs and outputs.

    ``omega`` natural frequencies (rad/s), ``zeta`` modal damping, ``b`` = M_m^-1 Phi^T B_o
    (n_modes x n_in), ``cq`` = C_oq Phi and ``cv`` = C_ov Phi (n_out x n_modes).
    """

    omega: np.ndarray
    zeta: np.ndarray
    modal_mass: np.ndarray
    b: np.ndarray
    cq: np.ndarray
    cv: np.ndarray
    rigid: tuple[int, ...]  # indices of the rigid-body modes
    inputs: tuple[str, ...] = tuple(STRUCT_INPUTS)
    outputs: tuple[str, ...] = tuple(STRUCT_OUTPUTS)

    @property
    def n_modes(self) -> int:
        return self.omega.size

    def select(self, modes) -> ModalModel:
        """Keep the listed modes (rigid modes must be among them to stay rigid)."""
        modes = np.asarray(modes)
        rigid = tuple(int(np.flatnonzero(modes == r)[0]) for r in self.rigid if r in modes)
        return ModalModel(self.omega[modes], self.zeta[modes], self.modal_mass[modes],
                          self.b[modes], self.cq[:, modes], self.cv[:, modes], rigid,
                          self.inputs, self.outputs)

    def to_ss(self, name: str = "structure") -> ct.StateSpace:
        """State-space model of Eq. (43): x = [q_m, dq_m/dt]."""
        m = self.n_modes
        A = np.block([[np.zeros((m, m)), np.eye(m)],
                      [-np.diag(self.omega ** 2), -np.diag(2 * self.zeta * self.omega)]])
        B = np.vstack([np.zeros((m, len(self.inputs))), self.b])
        C = np.hstack([self.cq, self.cv])
        states = [f"q{i}" for i in range(m)] + [f"dq{i}" for i in range(m)]
        return ss(A, B, C, np.zeros((len(self.outputs), len(self.inputs))),
                  list(self.inputs), list(self.outputs), name=name, states=states)


class StructureError(ValueError):
    """The structure section describes no antenna with exactly the two rigid-body modes."""


def modal_model(struct: LumpedStructure, zeta: float) -> ModalModel:
    """Modal data of the lumped structure: Eqs. (39)-(43).

    The rigid-body modes are the exact rigid rotations (so they stay pure az and el); the
    flexible modes come from the generalised eigenproblem ``K phi = w^2 M phi``, each scaled
    to a largest component of 1, with modal mass ``phi^T M phi``.
    """
    M, K = struct.M, struct.K
    w2, vecs = scipy.linalg.eigh(K, M)
    scale = np.max(np.abs(w2))
    n_rigid = int(np.sum(w2 < 1e-9 * scale))
    if n_rigid != 2:
        raise StructureError(
            f"section 'structure': {n_rigid} rigid-body modes instead of 2 (free azimuth and "
            f"elevation): a stiffness of the section (k_mesh_*, k_radial_*, k_az_chain, k_wheel_el, "
            f"k_counterweight, k_rib, k_hoop, k_quad) is too small to connect its part")
    flex = vecs[:, 2:] / np.max(np.abs(vecs[:, 2:]), axis=0)
    r_az, r_el = struct.rigid_mode("az"), struct.rigid_mode("el")
    # M-orthogonalise the el rigid mode against the az one (they couple through j_az_el)
    r_el = r_el - (r_az @ M @ r_el) / (r_az @ M @ r_az) * r_az
    phi = np.column_stack([r_az, r_el, flex])
    omega = np.concatenate([[0.0, 0.0], np.sqrt(w2[2:])])
    mm = np.einsum("ij,ij->j", phi, M @ phi)
    Bo = struct.input_matrix()
    Cq, Cv = struct.output_matrices()
    b = (phi.T @ Bo) / mm[:, None]  # Eq. (48): M_m^-1 Phi^T B_o
    zetas = np.full(omega.size, zeta)
    zetas[:2] = 0.0
    return ModalModel(omega, zetas, mm, b, Cq @ phi, Cv @ phi, (0, 1))
