"""Drive of one axis, [R] Section II.D, Eq. (38), Fig. 1.

The board (Eq. 10), the hydraulics (Eq. 34) and the gearbox (Eq. 37) closed as in Fig. 1: the
tachometer sees the motor rate divided by N_t.  State ``x_d = [x_b, x_h, x_g]`` (6 states);
inputs rate command ``r`` and pinion rate; output pinion torque ``T`` (C_d) and, for
diagnostics, the motor rate.

:func:`drive_ss` assembles the matrices of Eq. (38b) literally; :func:`drive_by_interconnection`
closes the same loops a second, independent way with :func:`control.interconnect`.
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

from dss14_env.model.gearbox import GearboxParams, gearbox_ss
from dss14_env.model.hydraulics import HydraulicParams, hydraulics_ss
from dss14_env.model.linsys import ss


@dataclass(frozen=True)
class DriveParams:
    """Everything one axis drive needs, resolved to SI (see calibration.resolve_drive)."""

    axis: str
    board: ct.StateSpace  # Eq. (10)
    hydraulics: HydraulicParams
    gearbox: GearboxParams
    n_t: float  # motor-to-tach ratio N_t
    n_p: float  # pinion-to-axis ratio (structure side)


def drive_ss(p: DriveParams) -> ct.StateSpace:
    """Drive state-space model by Eq. (38b): inputs ``r``, ``pinion_rate``; outputs ``T``, ``motor_rate``."""
    b, h, g = p.board, hydraulics_ss(p.hydraulics), gearbox_ss(p.gearbox)
    Ab, Bb1, Bb2, Cb = b.A, b.B[:, [0]], b.B[:, [1]], b.C
    Db1, Db2 = b.D[:, [0]], b.D[:, [1]]
    Ah, Bhi, Bho, Ch, Dhi, Dho = h.A, h.B[:, [0]], h.B[:, [1]], h.C, h.D[:, [0]], h.D[:, [1]]
    Ag, Bg1, Bg2, Cg1, Cg2 = g.A, g.B[:, [0]], g.B[:, [1]], g.C[[0], :], g.C[[1], :]
    Nt = p.n_t
    Z = np.zeros
    nb, nh = Ab.shape[0], Ah.shape[0]
    A = np.block([
        [Ab, Z((nb, nh)), Bb2 @ Cg2 / Nt],
        [Bhi @ Cb, Ah, Bho @ Cg2 + Bhi @ Db2 @ Cg2 / Nt],  # "D_be" of Eq. (38b) is D_b2
        [Bg1 @ Dhi @ Cb, Bg1 @ Ch, Ag + Bg1 @ Dho @ Cg2 + Bg1 @ Dhi @ Db2 @ Cg2 / Nt],
    ])
    B_r = np.vstack([Bb1, Bhi @ Db1, Bg1 @ Dhi @ Db1])
    B_t = np.vstack([Z((nb, 1)), Z((nh, 1)), Bg2])
    C_T = np.hstack([Z((1, nb)), Z((1, nh)), Cg1])
    C_m = np.hstack([Z((1, nb)), Z((1, nh)), Cg2])
    states = [f"{p.axis}.{s}" for s in (b.state_labels + h.state_labels + g.state_labels)]
    return ss(A, np.hstack([B_r, B_t]), np.vstack([C_T, C_m]), np.zeros((2, 2)),
              ["r", "pinion_rate"], ["T", "motor_rate"], name=f"drive_{p.axis}", states=states)


def drive_by_interconnection(p: DriveParams) -> ct.StateSpace:
    """The same drive built by :func:`control.interconnect` of the three blocks (Fig. 1)."""
    tach = ss([], [], [], [[1.0 / p.n_t]], ["motor_rate"], ["tach_rate"], name="tach")
    return ct.interconnect(
        [p.board, hydraulics_ss(p.hydraulics), gearbox_ss(p.gearbox), tach],
        inputs=["r", "pinion_rate"], outputs=["T", "motor_rate"], name=f"drive_ic_{p.axis}")
