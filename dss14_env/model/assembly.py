"""The assembled, calibrated DSS-14 model: drives, structure, rate loop, position loops.

>>> m = default_model()
>>> m.rate_loop.nstates, m.structure.n_modes, m.structure_full.n_modes
(60, 24, 150)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import control as ct
import numpy as np

from dss14_env.core.schema import ConfigError
from dss14_env.core.threads import single_threaded
from dss14_env.core.units import AXES
from dss14_env.model.calibration import (
    Calibration,
    CalibrationError,
    calibrate,
    drive_params,
    structure_models,
)
from dss14_env.model.config import ModelConfig, load_model_config
from dss14_env.model.drive import DriveParams, drive_ss
from dss14_env.model.loops import position_loop, rate_loop
from dss14_env.model.structure import ModalModel, StructureError


@dataclass
class DSS14Model:
    """Calibrated model built from a configuration.

    :param cfg: validated configuration (SI)
    :param calibration: result of :func:`dss14_env.model.calibration.calibrate` for ``cfg``
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


@single_threaded
def build_model(cfg: ModelConfig | None = None) -> DSS14Model:
    """Load (default config if ``None``), calibrate and assemble the model (about 2 s).

    Built with one BLAS thread (:func:`dss14_env.core.threads.single_threaded`), structure and
    rate loop included, so the model is bit-for-bit the same whatever the caller's threads.
    """
    cfg = cfg if cfg is not None else load_model_config()
    try:
        model = DSS14Model(cfg, calibrate(cfg))
        model.rate_loop  # noqa: B018  (builds the structures and the rate loop now)
    except (StructureError, CalibrationError) as exc:  # name the file the problem comes from
        raise ConfigError(f"{cfg.path}: {exc}") from None
    except ConfigError:
        raise
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:  # values out of numbers' reach
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:160]
        raise ConfigError(f"{cfg.path}: the model cannot be built from these values "
                          f"({type(exc).__name__}: {first})") from None
    return model


@lru_cache(maxsize=1)
def default_model() -> DSS14Model:
    """The model of the shipped configuration, built once per process."""
    return build_model()
