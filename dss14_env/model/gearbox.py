"""Gearbox, [R] Section II.C, Eqs. (35)-(37), Fig. 10.

States ``x_g = [omega_m, T]`` (motor rate rad/s, pinion torque N*m); inputs motor torque
``T_o`` and pinion rate; outputs pinion torque ``T`` (C_g1) and motor rate (C_g2)::

    J_m d(omega_m)/dt = T_o - T/N                     Eq. (35a)
    dT/dt = k_g (omega_m / N - dtheta_p/dt)           Eq. (35b) differentiated
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct

from dss14_env.model.linsys import ss


@dataclass(frozen=True)
class GearboxParams:
    """Resolved gearbox parameters of one axis (SI)."""

    j_m: float  # motor-side inertia, kg*m^2
    n: float  # motor-to-pinion ratio N
    k_g: float  # gearbox stiffness at the pinion, N*m/rad


def gearbox_ss(p: GearboxParams, axis: str = "") -> ct.StateSpace:
    """State-space gearbox of Eq. (37): inputs ``T_o``, ``pinion_rate``; outputs ``T``, ``motor_rate``."""
    A = [[0.0, -1.0 / (p.n * p.j_m)], [p.k_g / p.n, 0.0]]
    B = [[1.0 / p.j_m, 0.0], [0.0, -p.k_g]]  # [B_g1, B_g2]
    C = [[0.0, 1.0], [1.0, 0.0]]  # [C_g1; C_g2]
    return ss(A, B, C, [[0, 0], [0, 0]], ["T_o", "pinion_rate"], ["T", "motor_rate"],
              name=f"gearbox_{axis}", states=["omega_m", "T"])
