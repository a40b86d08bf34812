"""The yardstick: the full-order H2-optimal (LQG) controller for the benchmark's own cost.

Benchmark cost per step (the environment's reward, negated)::

    J = E[ |e_k|^2 / sigma_e^2 + w |a_k - a_{k-1}|^2 ]

with ``e`` the true servo errors, ``sigma_e`` the error scale (10 mdeg), ``a = r / s_a`` the
action and ``w`` the action-change weight.  The plant is the FULL nominal model: the 58-state
stable part of the rate loop plus the two encoder integrators (the 60-state rate loop, exact),
the scenario's own wind (4-state Davenport filter at the scenario speed, coherent gust with the
scenario direction's gains) -- 64 states -- plus the previous command (2 states) that the
action-change penalty needs, discretised exactly for the control period.  The measurement is the
encoder with the quantisation modelled as white noise of variance ``q^2 / 12``.

For this linear-Gaussian problem the optimal controller among ALL causal controllers that see
the same measurements is the LQG (separation principle): a steady-state Kalman filter (DARE) and
an LQR on the augmented state with the cross term of the action change (DARE).  No linear
controller with the same measurements does better on this cost, whatever its order or
structure; every reduced-order, constrained or learned controller is therefore scored as a
multiple of the yardstick's expected error.  Its expected 3-sigma error and cost come from the
Riccati solutions through the closed-loop stationary covariance (discrete Lyapunov equation,
:func:`dss14_env.baselines.analysis.stationary_performance`);
:func:`~dss14_env.baselines.analysis.riccati_cost` gives the same cost from
the two Riccati solutions alone (checked in the tests).

Two caveats, both reported: the optimality is for the model (quantisation as white noise, no
command limiter, mean torque known); in the simulator the encoder is truly quantised, so the
simulated yardstick is a reference controller, not a bound.  The mean wind torque is a known
constant of the scenario: the runnable :class:`YardstickController` removes it with the start
command (bumpless start) like the other controllers.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from dss14_env.baselines.analysis import closed_loop, lqg_as_linear, riccati_cost, stationary_performance
from dss14_env.baselines.design import build_design_model
from dss14_env.baselines.interface import ControlInterface, as_interface
from dss14_env.baselines.lqg import EstimatorController, LQGDesign, design_lqg
from dss14_env.core.units import KMH
from dss14_env.wind.loads import direction_angle

#: tiny random walk of the command-level disturbance in the runnable yardstick (fraction of
#: the rate limit per step): keeps it offset-free on a plant whose start gust is unknown
RUNNABLE_DRIFT = 1e-6
#: tiny command noise that keeps the Kalman problem regular when the coherent gust leaves one
#: combination of the two encoder integrators undriven (front or side wind: rank-1 gust)
REGULARISING_INPUT_NOISE = 1e-6


def yardstick_design(spec: ControlInterface, wind_speed: float, direction: str | float,
                     runnable: bool = False) -> LQGDesign:
    """See :func:`_yardstick_design` (cached)."""
    direction = direction if isinstance(direction, str) else float(direction)
    return _yardstick_design(spec, float(wind_speed), direction, bool(runnable))


@lru_cache(maxsize=32)
def _yardstick_design(spec: ControlInterface, wind_speed: float, direction: str | float,
                      runnable: bool = False) -> LQGDesign:
    """The full-order H2-optimal design for one scenario wind.

    :param spec: environment interface (period, scales, weight, encoder)
    :param wind_speed: mean wind speed, m/s (> 0)
    :param direction: ``"front"``, ``"side"`` or an angle in rad relative to the dish
    :param runnable: add the command-level disturbance estimate used in simulation
    """
    if not (math.isfinite(wind_speed) and wind_speed > 0):
        raise ValueError(f"the yardstick needs a positive wind speed (m/s), got {wind_speed!r}")
    direction = direction if isinstance(direction, str) else float(direction_angle(direction))
    dm = build_design_model(spec.dt, order=None, wind=(float(wind_speed), direction),
                            encoder_noise=spec.encoder_noise, bits=spec.encoder_bits)
    return design_lqg(dm, spec.weights, w_e=1.0, w_a=1.0, w_i=None,
                      input_noise=REGULARISING_INPUT_NOISE,
                      disturbance_drift=RUNNABLE_DRIFT if runnable else None,
                      rate_limit=spec.rate_limit)


def expected_performance(spec: ControlInterface | Any, wind_speed: float, direction: str | float) -> dict:
    """See :func:`_expected_performance` (cached per interface and wind; a copy is returned)."""
    spec = as_interface(spec)
    direction = direction if isinstance(direction, str) else float(direction)
    return copy.deepcopy(_expected_performance(spec, float(wind_speed), direction))


@lru_cache(maxsize=32)
def _expected_performance(spec: ControlInterface, wind_speed: float, direction: str | float) -> dict:
    """The yardstick's expected 3-sigma servo errors (mdeg) and per-step cost.

    :return: dict (JSON-ready): ``three_sigma_mdeg`` [az, el], ``rms_mdeg``, ``cost``,
        ``cost_riccati`` (the same cost from the Riccati solutions), ``n_states`` of the plant
        model and the Riccati residuals
    """
    d = yardstick_design(spec, wind_speed, direction)
    perf = stationary_performance(closed_loop(d.dm, lqg_as_linear(d)), spec.weights)
    perf.update({"cost_riccati": riccati_cost(d), "n_states": d.dm.n, "n_augmented": d.n_z,
                 "residuals": d.residuals, "wind_speed_mps": float(wind_speed),
                 "direction": direction if isinstance(direction, str) else float(direction)})
    return perf


class YardstickController(EstimatorController):
    """The yardstick as a controller (full-order LQG for the scenario's wind).

    It is an oracle of the scenario's disturbance model: the runner tells it the episode's
    wind speed and direction (:meth:`set_scenario`, or :meth:`set_scenario_batch` for rows,
    from the environment's reset info) and it designs for them (cached per wind).  Without
    wind it has nothing to be optimal for and uses a 1 m/s wind of the same direction.

    :param env: the environment (or its config / a :class:`ControlInterface`)
    :param wind_speed: initial design wind speed, m/s
    :param direction: initial design direction
    :param name: label, default ``"yardstick"``
    """

    def __init__(self, env: Any = None, wind_speed: float = 50 * KMH,
                 direction: str | float = "front", name: str = "yardstick") -> None:
        interface = as_interface(env)
        self.interface = interface
        self._designs_by_wind: dict[tuple, LQGDesign] = {}
        self._scenarios: list[tuple[float, str | float]] | None = None
        super().__init__(self.design_for(wind_speed, direction), interface, name)

    def design_for(self, speed: float, direction: str | float) -> LQGDesign:
        """The runnable yardstick design for a wind (speed at least 1 m/s; cached)."""
        speed = max(float(speed), 1.0)
        key = (round(speed, 9), direction if isinstance(direction, str) else round(float(direction), 9))
        if key not in self._designs_by_wind:
            self._designs_by_wind[key] = yardstick_design(self.interface, speed, direction, runnable=True)
        return self._designs_by_wind[key]

    def reset(self, seed: int | None = None) -> None:
        """New episode; it uses the wind of the last :meth:`set_scenario` (rows' winds of
        :meth:`set_scenario_batch` are forgotten).
        """
        self._scenarios = None
        super().reset(seed)

    def set_scenario(self, wind_speed: float, direction: str | float) -> None:
        """Design for the episode's wind (call before the episode's first :meth:`act`)."""
        self.default_design = self.design_for(wind_speed, direction)

    def set_scenario_batch(self, wind_speeds: Sequence[float], directions: Sequence[str | float]) -> None:
        """The rows' winds: row ``i``'s next episode (its first :meth:`act_batch` after
        :meth:`reset_batch` or :meth:`restart`) is designed for ``(wind_speeds[i],
        directions[i])`` (m/s; ``"front"``, ``"side"`` or rad).

        :raises ValueError: naming the argument if it has not one finite entry per row
        """
        speeds = np.asarray(wind_speeds, float)
        if speeds.shape != (self.n,) or not np.all(np.isfinite(speeds)) or np.any(speeds < 0):
            raise ValueError(f"wind_speeds must be {self.n} finite speeds >= 0 (one per row), got "
                             f"{np.asarray(wind_speeds).tolist()}")
        if len(directions) != self.n:
            raise ValueError(f"directions must have one entry per row ({self.n}), got {len(directions)}")
        dirs = [d if isinstance(d, str) else float(d) for d in directions]
        for d in dirs:
            direction_angle(d)  # validates: a known name or a finite angle
        self._scenarios = list(zip(speeds.tolist(), dirs, strict=True))

    def select_designs(self, rows: np.ndarray, r0: np.ndarray, c_rate0: np.ndarray) -> list[LQGDesign]:
        if self._scenarios is None:
            return [self.default_design] * len(rows)
        if len(self._scenarios) != self.n:
            raise ValueError(f"set_scenario_batch was given {len(self._scenarios)} rows, the batch "
                             f"has {self.n}")
        return [self.design_for(*self._scenarios[i]) for i in rows.tolist()]
