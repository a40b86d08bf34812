"""Hydraulic system, [R] Section II.B, Eqs. (11)-(34), Tables 1-3.

States ``x_h = [dq_v/dt, q_v, p]`` (m^3/s^2, m^3/s, Pa); inputs valve current ``i`` (A) and
motor rate (rad/s); output motor torque ``T_o`` (N*m).  Eq. (34b)::

    A_h = [[-2 z w, -w^2, 0], [1, 0, 0], [0, k_l, -k_l c]],   c = 3 k_a2/mu + 2 k_p + 2 k_s
    B_hi = [2 w^2 k_a, 0, 0]^T,  B_ho = [0, 0, -2 k_l D]^T,  C_h = [0, 0, D],
    D_hi = 0,  D_ho = -k_v D mu

with ``k_l = beta / v_o`` (Eq. 33).  Eq. (34b) prints C_h as a column; it is a row.
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct

from dss14_env.model.linsys import ss


@dataclass(frozen=True)
class HydraulicParams:
    """Resolved hydraulic parameters of one axis (SI)."""

    zeta_o: float  # valve damping ratio, Eq. (11)
    omega_o: float  # valve natural frequency, rad/s
    k_a: float  # valve flow gain, m^3/s/A (calibrated, see calibration.py)
    k_s: float  # shorting-valve gain, m^3/s/Pa, Eq. (13)
    k_p: float  # passive-valve gain, m^3/s/Pa, Eq. (15)
    k_a2: float  # motor leakage constant, m^3, Eq. (19)
    mu: float  # viscosity, Pa*s
    d: float  # lumped motor displacement, m^3/rad
    k_v: float  # viscous friction coefficient, Eq. (28)
    beta: float  # bulk modulus, Pa
    v_o: float  # line volume, m^3

    @property
    def k_l(self) -> float:
        """Line gain beta / v_o, Pa/m^3, Eq. (33)."""
        return self.beta / self.v_o

    @property
    def leakage(self) -> float:
        """Total flow-pressure coefficient 3 k_a2/mu + 2 k_p + 2 k_s, m^3/s/Pa, Eqs. (30), (32)."""
        return 3.0 * self.k_a2 / self.mu + 2.0 * self.k_p + 2.0 * self.k_s


def hydraulics_ss(p: HydraulicParams, axis: str = "") -> ct.StateSpace:
    """State-space hydraulic model of Eq. (34): inputs ``i``, ``motor_rate``; output ``T_o``."""
    w, z, kl = p.omega_o, p.zeta_o, p.k_l
    A = [[-2 * z * w, -w * w, 0.0], [1.0, 0.0, 0.0], [0.0, kl, -kl * p.leakage]]
    B = [[2 * w * w * p.k_a, 0.0], [0.0, 0.0], [0.0, -2 * kl * p.d]]  # [B_hi, B_ho]
    C = [[0.0, 0.0, p.d]]  # C_h
    D = [[0.0, -p.k_v * p.d * p.mu]]  # [D_hi, D_ho]
    return ss(A, B, C, D, ["i", "motor_rate"], ["T_o"], name=f"hydraulics_{axis}",
              states=["dq_v", "q_v", "p"])
