"""Parameter uncertainty of the model: the report's parameter ranges, the stability sweep over
them and random draws of a stable plant.

The hydraulic parameters of :data:`SWEEP_PARAMS` have ranges in ``configs/model.yaml`` ([R]
Tables 1-3).  :func:`perturbed_rate_loop` rebuilds the rate loop (Eq. 56) with some of them
replaced and the calibration held; :func:`stability_sweep` grids the ranges (the reproduction's
stability rows); :func:`draw_stable_params` draws a stable parameter set (the environments'
``randomize_params``).
"""

from __future__ import annotations

import itertools
import math

import control as ct
import numpy as np

from dss14_env.core.units import AXES
from dss14_env.model.assembly import DSS14Model, default_model
from dss14_env.model.calibration import drive_params
from dss14_env.model.drive import drive_ss
from dss14_env.model.loops import position_loop, rate_loop

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
            vals = dict(zip(params, combo, strict=True))
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


# ---------------------------------------------------------------------- parameter randomisation
#: margins of the stability test of a randomised draw (1/s): the rate loop's slowest
#: non-rigid pole and the PI loop's slowest pole must lie left of -margin
RATE_LOOP_MARGIN = 0.0
PI_LOOP_MARGIN = 0.01
_MAX_DRAWS = 200


def draw_stable_params(rng: np.random.Generator, gain_set: str = "kp1",
                       model: DSS14Model | None = None) -> dict[str, float]:
    """Draw the uncertain hydraulic parameters over the report's ranges, stable part only.

    Each parameter of :data:`dss14_env.model.uncertainty.SWEEP_PARAMS` is drawn log-uniformly over its
    ``range`` in ``configs/model.yaml`` (the grid of :func:`dss14_env.model.uncertainty.stability_sweep` is
    log-spaced too).  A draw is rejected and redrawn unless the rate loop is stable apart from
    its two rigid-body integrators and the PI position loop of ``gain_set`` (the report's
    kp 1, ki 0.3 by default) has every pole left of -:data:`PI_LOOP_MARGIN` 1/s.  About 10 %
    of the box is rejected (docs/model.md section 9: low viscosity with high leakage).

    :param rng: the only source of randomness
    :param gain_set: PI gain set of the stability test
    :param model: the model whose ranges and rate loop are used, default
        :func:`dss14_env.model.default_model`
    :return: ``{name: value}`` in SI
    """
    model = model if model is not None else default_model()
    kp, ki = model.gains(gain_set)
    for _ in range(_MAX_DRAWS):
        vals = {}
        for name in SWEEP_PARAMS:
            lo, hi = model.cfg.params[name].range
            vals[name] = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
        rl = perturbed_rate_loop(model, vals)
        if rate_loop_stable(rl.A) and pi_loop_abscissa(rl, kp, ki) < -PI_LOOP_MARGIN:
            return vals
    raise RuntimeError(f"no stable parameter draw in {_MAX_DRAWS} tries")


def rate_loop_stable(A: np.ndarray) -> bool:
    """True if every pole of the rate loop but its two rigid-body integrators (at 0) is stable."""
    re = np.sort(np.linalg.eigvals(A).real)
    return bool(re[-3] < -RATE_LOOP_MARGIN and np.all(np.abs(re[-2:]) < 1e-9))


def pi_loop_abscissa(rate_loop: ct.StateSpace, kp: tuple[float, float], ki: tuple[float, float]) -> float:
    """Largest pole real part (1/s) of the continuous PI position loop around ``rate_loop``."""
    return float(np.max(np.linalg.eigvals(position_loop(rate_loop, kp, ki).A).real))
