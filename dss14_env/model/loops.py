"""Rate loop, [R] Eq. (56), and PI position loop, [R] Eqs. (57)-(61).

Rate loop (Fig. 16): the az and el drives (Eq. 38) on the structure (Eq. 44); each drive's
torque ``T`` is the structure's pinion torque and the structure's pinion rate feeds back to
the drive.  State ``x_r = [x_da, x_de, x_s]``; inputs rate commands ``r_a``, ``r_e`` (axis
rad/s) and the wind torques; outputs the structure outputs plus the drive torques.

Position loop (Fig. 18): integrators of the servo errors (Eq. 57), PI law (Eq. 58), closed with
``e = c - theta`` (Eq. 60), ``A_cl = A_o - B_o C_o`` (Eq. 61b).  The errors are in axis
radians, so ``kp`` is in 1/s and ``ki`` in 1/s^2 (docs/model.md, units).
"""

from __future__ import annotations

import control as ct
import numpy as np

from dss14_env.model.linsys import ss

WIND_INPUTS = ["Tw_az", "Tw_el"]


def rate_loop(drive_az: ct.StateSpace, drive_el: ct.StateSpace, structure: ct.StateSpace) -> ct.StateSpace:
    """Rate-loop state-space model, Eq. (56b)."""
    s = structure
    si, so = s.input_labels, s.output_labels
    Bsa, Bse = s.B[:, [si.index("T_a")]], s.B[:, [si.index("T_e")]]
    Bw = s.B[:, [si.index(n) for n in WIND_INPUTS]]
    Cpa, Cpe = s.C[[so.index("pinion_rate_az")]], s.C[[so.index("pinion_rate_el")]]
    da, de = drive_az, drive_el
    Bdra, Bdta = da.B[:, [0]], da.B[:, [1]]
    Bdre, Bdte = de.B[:, [0]], de.B[:, [1]]
    Cda, Cde = da.C[[0]], de.C[[0]]  # torque rows
    na, ne, ns = da.nstates, de.nstates, s.nstates
    Z = np.zeros
    A = np.block([
        [da.A, Z((na, ne)), Bdta @ Cpa],
        [Z((ne, na)), de.A, Bdte @ Cpe],
        [Bsa @ Cda, Bse @ Cde, s.A],
    ])
    B = np.block([
        [Bdra, Z((na, 1)), Z((na, 2))],
        [Z((ne, 1)), Bdre, Z((ne, 2))],
        [Z((ns, 1)), Z((ns, 1)), Bw],
    ])
    C = np.block([
        [Z((len(so), na)), Z((len(so), ne)), s.C],  # C_r = [0 0 C_s]
        [Cda, Z((1, ne)), Z((1, ns))],
        [Z((1, na)), Cde, Z((1, ns))],
        [da.C[[1]], Z((1, ne)), Z((1, ns))],
        [Z((1, na)), de.C[[1]], Z((1, ns))],
    ])
    outputs = list(so) + ["T_a", "T_e", "motor_rate_az", "motor_rate_el"]
    states = list(da.state_labels) + list(de.state_labels) + list(s.state_labels)
    return ss(A, B, C, Z((len(outputs), 4)), ["r_a", "r_e"] + WIND_INPUTS, outputs,
              name="rate_loop", states=states)


def position_loop(rl: ct.StateSpace, kp: tuple[float, float], ki: tuple[float, float],
                  encoders: tuple[str, str] = ("enc_az", "enc_el")) -> ct.StateSpace:
    """Closed PI position loop, Eqs. (57)-(61).

    :param rl: rate loop from :func:`rate_loop`
    :param kp: proportional gains (az, el), 1/s
    :param ki: integral gains (az, el), 1/s^2
    :param encoders: rate-loop outputs that close the loop (theta_a, theta_e)
    :return: system with inputs ``c_a, c_e`` (commands, rad) and the wind torques; outputs the
        rate-loop outputs plus servo errors ``e_a, e_e`` and rate commands ``r_a, r_e``.
    """
    n = rl.nstates
    il, ol = rl.input_labels, rl.output_labels
    Bra, Bre = rl.B[:, [il.index("r_a")]], rl.B[:, [il.index("r_e")]]
    Bw = rl.B[:, [il.index(w) for w in WIND_INPUTS]]
    Ca, Ce = rl.C[[ol.index(encoders[0])]], rl.C[[ol.index(encoders[1])]]
    Z = np.zeros
    # Eq. (59b)
    Ao = np.block([[Z((2, 2)), Z((2, n))], [ki[0] * Bra, ki[1] * Bre, rl.A]])
    Bo = np.block([[np.eye(2)], [kp[0] * Bra, kp[1] * Bre]])
    Co = np.block([[Z((1, 2)), Ca], [Z((1, 2)), Ce]])
    Acl = Ao - Bo @ Co  # Eq. (61b)
    Bw_cl = np.vstack([Z((2, 2)), Bw])
    C = np.vstack([np.hstack([Z((rl.noutputs, 2)), rl.C]),
                   -Co,  # e = c - theta: the c part goes in D
                   np.hstack([np.diag(ki), Z((2, n))]) - np.diag(kp) @ Co])
    D = np.vstack([Z((rl.noutputs, 4)),
                   np.hstack([np.eye(2), Z((2, 2))]),
                   np.hstack([np.diag(kp), Z((2, 2))])])
    outputs = list(ol) + ["e_a", "e_e", "r_a", "r_e"]
    states = ["x_ai", "x_ei"] + list(rl.state_labels)
    return ss(Acl, np.hstack([Bo, Bw_cl]), C, D, ["c_a", "c_e"] + WIND_INPUTS, outputs,
              name="position_loop", states=states)
