"""The assembled, calibrated DSS-14 model: drives, structure, rate loop, position loops.

>>> m = default_model()
>>> m.rate_loop.nstates, m.structure.n_modes, m.structure_full.n_modes
(60, 24, 150)
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import cached_property, lru_cache

import control as ct
import numpy as np

from .calibration import Calibration, calibrate, drive_params, structure_models
from .config import AXES, ModelConfig, load_model_config
from .drive import DriveParams, drive_ss
from .loops import position_loop, rate_loop
from .structure import ModalModel


@dataclass
class DSS14Model:
    """Calibrated model built from a configuration.

    :param cfg: validated configuration (SI)
    :param calibration: result of :func:`dss14_env.calibration.calibrate` for ``cfg``
    """

    cfg: ModelConfig
    calibration: Calibration

    @cached_property
    def _structures(self) -> tuple[ModalModel, ModalModel, np.ndarray]:
        c = self.calibration
        return structure_models(self.cfg, c.az_chain_scale, c.j_az_el)

    @property
    def structure_full(self) -> ModalModel:
        """The 150-mode FE-like modal model (Eqs. 39-54)."""
        return self._structures[0]

    @property
    def structure(self) -> ModalModel:
        """The reduced model: 2 rigid + 22 flexible modes (Eq. 55)."""
        return self._structures[1]

    @property
    def kept_modes(self) -> np.ndarray:
        return self._structures[2]

    def drive_params(self, axis: str) -> DriveParams:
        c = self.calibration
        return drive_params(self.cfg, axis, c.lam[axis], c.kappa[axis], c.k_g[axis])

    def drive(self, axis: str) -> ct.StateSpace:
        """Drive of one axis, Eq. (38)."""
        return drive_ss(self.drive_params(axis))

    @cached_property
    def rate_loop(self) -> ct.StateSpace:
        """Rate loop, Eq. (56): inputs r_a, r_e, Tw_az, Tw_el."""
        return rate_loop(self.drive("az"), self.drive("el"), self.structure.to_ss())

    def gains(self, gain_set: str) -> tuple[tuple[float, float], tuple[float, float]]:
        if gain_set not in self.cfg.gain_sets:
            raise KeyError(f"unknown gain set {gain_set!r}; known: {list(self.cfg.gain_sets)}")
        g = self.cfg.gain_sets[gain_set]
        return (g.kp, g.kp), (g.ki, g.ki)

    def position_loop(self, gain_set: str) -> ct.StateSpace:
        """Closed PI position loop, Eqs. (57)-(61), for a named gain set of the config."""
        kp, ki = self.gains(gain_set)
        return position_loop(self.rate_loop, kp, ki)

    def derived(self) -> dict:
        """Calibrated and derived constants per axis, in SI (for docs and metrics)."""
        out = {"j_az_el_kgm2": self.calibration.j_az_el,
               "az_chain_scale": list(self.calibration.az_chain_scale)}
        for ax in AXES:
            p = self.drive_params(ax)
            out[ax] = {"lambda": self.calibration.lam[ax], "kappa": self.calibration.kappa[ax],
                       "k_a_m3_per_s_per_A": p.hydraulics.k_a, "gear_ratio_N": p.gearbox.n,
                       "k_g_Nm_per_rad": p.gearbox.k_g,
                       "k_a_over_report_max": p.hydraulics.k_a / self.cfg.hydraulics.k_a_report}
        return out


def build_model(cfg: ModelConfig | None = None) -> DSS14Model:
    """Load (default config if ``None``), calibrate and assemble the model (about 2 s)."""
    cfg = cfg if cfg is not None else load_model_config()
    return DSS14Model(cfg, calibrate(cfg))


@lru_cache(maxsize=1)
def default_model() -> DSS14Model:
    """The model of the shipped configuration, built once per process."""
    return build_model()


# ------------------------------------------------------------------------ stability sweep
SWEEP_PARAMS = ("hydraulics.zeta_o", "hydraulics.k_s", "hydraulics.mu", "hydraulics.k_a2",
                "hydraulics.k_a_report")


def perturbed_rate_loop(model: DSS14Model, values: dict) -> ct.StateSpace:
    """Rate loop with hydraulic parameters replaced (SI), calibration kept.

    ``hydraulics.k_a_report`` scales the calibrated valve gain by value / nominal, i.e. the
    model's k_a moves over the report's relative spread (59,200-97,300 ratio).
    """
    cfg = model.cfg
    cfg2 = cfg.replace(**{f"hydraulics__{k.split('.')[1]}": v for k, v in values.items()
                          if k != "hydraulics.k_a_report"})
    ka_scale = values.get("hydraulics.k_a_report", cfg.hydraulics.k_a_report) / cfg.hydraulics.k_a_report
    c = model.calibration
    drives = {ax: drive_ss(drive_params(cfg2, ax, c.lam[ax] * ka_scale, c.kappa[ax], c.k_g[ax]))
              for ax in AXES}
    return rate_loop(drives["az"], drives["el"], model.structure.to_ss())


def stability_sweep(model: DSS14Model, params=SWEEP_PARAMS, levels: int = 3) -> dict:
    """Grid over the report's parameter ranges: stable share and worst margin of both loops.

    :param levels: grid points per parameter (log-spaced over each range), default 3
    :return: dict with ``n``, ``stable_share`` per gain set, ``worst_abscissa`` (largest real
        part of the closed-loop poles, 1/s), the worst combination and the unstable ones
    """
    grids = []
    for name in params:
        p = model.cfg.params[name]
        lo, hi = p.range
        grids.append(np.geomspace(lo, hi, levels))
    result = {"n": 0, "params": list(params), "gain_sets": {}}
    combos = list(itertools.product(*grids))
    result["n"] = len(combos)
    for gname in model.cfg.gain_sets:
        kp, ki = model.gains(gname)
        worst, worst_combo, unstable = -np.inf, None, []
        for combo in combos:
            vals = dict(zip(params, combo))
            pl = position_loop(perturbed_rate_loop(model, vals), kp, ki)
            a = float(np.max(np.linalg.eigvals(pl.A).real))
            if a > worst:
                worst, worst_combo = a, vals
            if a >= 0:
                unstable.append(vals)
        result["gain_sets"][gname] = {
            "stable_share": 1.0 - len(unstable) / len(combos), "worst_abscissa": worst,
            "worst_combination": worst_combo, "unstable": unstable}
    return result
