"""Electronics board, [R] Section II.A, Eqs. (1)-(10) and the Appendix.

Rate command ``r`` (axis rad/s) and tachometer rate (rad/s) in, valve current ``i`` (A) out::

    G_o = (1 + 0.400 s) / (1 + 4.205 s)                      Eq. (4)
    G_r = k_r G_r1 G_s       = 0.3323 G_o                    Eq. (6)
    G_t = k_t G_to G_r2 G_s  = -0.7750e-4 G_o (az)           Eqs. (7)-(8)

Both paths share the lag compensator, so the minimal realisation of Eq. (10) has one state.

>>> from dss14_env.model.config import load_model_config
>>> cfg = load_model_config()
>>> round(board_dc_gains(cfg, "az")[0], 4), round(board_dc_gains(cfg, "az")[1] * 1e4, 3)
(0.3323, -0.776)
"""

from __future__ import annotations

import control as ct

from dss14_env.model.config import ModelConfig
from dss14_env.model.linsys import ss


def board_dc_gains(cfg: ModelConfig, axis: str) -> tuple[float, float]:
    """DC gains ``(G_r(0), G_t(0))`` of Eqs. (6) and (7), in A/(rad/s)."""
    b = cfg.board
    g_r = b.k_r * b.g_r1 * b.g_s  # Eq. (6)
    g_t = b.k_t * b.g_to[axis] * b.g_r2 * b.g_s  # Eq. (7)
    return g_r, g_t


def board_ss(cfg: ModelConfig, axis: str) -> ct.StateSpace:
    """State-space board model, Eq. (10): inputs ``r``, ``tach_rate``; output ``i``.

    ``G_o = tz/tp + (1 - tz/tp) / (1 + tp s)``, realised with the single state ``x_b``.
    """
    b = cfg.board
    g_r, g_t = board_dc_gains(cfg, axis)
    tz, tp = b.tau_zero, b.tau_pole
    A = [[-1.0 / tp]]
    B = [[g_r / tp, g_t / tp]]  # [B_b1, B_b2]
    C = [[1.0 - tz / tp]]  # C_b
    D = [[g_r * tz / tp, g_t * tz / tp]]  # [D_b1, D_b2]
    return ss(A, B, C, D, ["r", "tach_rate"], ["i"], name=f"board_{axis}", states=["x_b"])
