"""The yardsticks: the full-order H2-optimal (LQG) controllers for the benchmark's quadratic costs.

Two quadratic costs per step, both with the environment's action-change term::

    J_enc   = E[ |e_k|^2 / sigma_e^2   + w |a_k - a_{k-1}|^2 ]     (the environment's reward)
    J_point = E[ |e_p,k|^2 / sigma_e^2 + w |a_k - a_{k-1}|^2 ]

with ``e`` the true servo errors at the drive encoders (az, el), ``e_p`` the dish's true
pointing errors (el, xel: the command less the structure's pointing angles, deformation
included), ``sigma_e`` the error scale (10 mdeg), ``a = r / s_a`` the action and ``w`` the
action-change weight.  The *encoder yardstick* minimises ``J_enc``, the *pointing yardstick*
``J_point``; both see the same measurements, the drive encoders.  The plant is the FULL
nominal model (or, with ``plants=``, a drive variant's model and its wind loads): the 58-state
stable part of the rate loop plus the two encoder integrators (the
60-state rate loop, exact, its deformation outputs kept), the scenario's own wind (4-state
Davenport filter at the scenario speed, coherent gust with the scenario direction's gains) --
64 states -- plus the previous command (2 states) that the action-change penalty needs,
discretised exactly for the control period.  The measurement is the encoder with the
quantisation modelled as white noise of variance ``q^2 / 12``.

**What a yardstick bounds.**  For this linear-Gaussian problem the optimal controller among ALL
causal controllers that see the same measurements is the LQG (separation principle): a
steady-state Kalman filter (DARE) and an LQR on the augmented state with the cross term of the
action change (DARE).  So no controller with the same measurements has a smaller expected
*cost J* on the model (quantisation as white noise, no command limiter, mean torque known),
whatever its order, structure or nonlinearity.  That is all it bounds: it is not a bound on
the 3σ error the bench ranks by.  A controller that spends more action change (a smaller
``w``) gets a smaller error at a larger cost: the encoder LQG designed with ``w = 1e-3`` has
0.239 / 0.109 mdeg 3σ on the loaded axis in 50 km/h front / side wind against the encoder
yardstick's 0.363 / 0.137.  The 3σ reference is therefore the *error-only limit*
(:func:`error_only_limit`): the same design with the action-change weight taken to zero
(:data:`ERROR_ONLY_WEIGHT`), reported with the acceleration it needs, which is far beyond the
0.2 deg/s^2 limit of the command limiter for the pointing error: it is the linear limit of the
measurements, not an achievable figure.  Every controller is scored as a multiple of the
yardstick's expected error of its own kind (``vs_yardstick`` for the servo error).  The
expected 3-sigma errors and costs come from the Riccati solutions through the closed-loop
stationary covariance (discrete Lyapunov equation,
:func:`dss14_env.baselines.analysis.stationary_performance`);
:func:`~dss14_env.baselines.analysis.riccati_cost` gives the same cost from the two Riccati
solutions alone (checked in the tests).

Two caveats, both reported: the optimality is for the model (quantisation as white noise, no
command limiter, mean torque known); in the simulator the encoder is truly quantised, so the
simulated yardstick is a reference controller, not a bound.  The mean wind torque is a known
constant of the scenario: the runnable :class:`YardstickController` removes it with the start
command (bumpless start) like the other controllers; the pointing yardstick also takes out its
static deflection (as the pointing LQG, :class:`dss14_env.baselines.lqg.PointingLQGController`).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from dss14_env.baselines.analysis import (
    closed_loop,
    design_measurement,
    lqg_as_linear,
    pi_as_linear,
    riccati_cost,
    stationary_performance,
)
from dss14_env.baselines.design import build_design_model
from dss14_env.baselines.interface import ControlInterface, as_interface
from dss14_env.baselines.lqg import EstimatorController, LQGDesign, design_lqg
from dss14_env.core.units import KMH, R2D
from dss14_env.wind.loads import direction_angle

#: tiny random walk of the command-level disturbance in the runnable yardstick (fraction of
#: the rate limit per step): keeps it offset-free on a plant whose start gust is unknown
RUNNABLE_DRIFT = 1e-6
#: tiny command noise that keeps the Kalman problem regular when the coherent gust leaves one
#: combination of the two encoder integrators undriven (front or side wind: rank-1 gust)
REGULARISING_INPUT_NOISE = 1e-6
#: the yardsticks' errors: the servo error at the drive encoders, the dish's pointing error
ERRORS = ("encoder", "pointing")
#: the action-change multiplier of the error-only limit (``w -> 0``).  The encoder yardstick's
#: 3σ has converged here (within ~1 % of its value at 1e-8) at accelerations of 3-15 deg/s^2;
#: the pointing yardstick's has not and has no finite limit worth the name: it still falls
#: (1.01 -> 0.92 mdeg side xel from 1e-6 to 1e-8) while its acceleration grows without bound
#: (hundreds of deg/s^2) -- the law inverts the structure's dynamics
ERROR_ONLY_WEIGHT = 1e-6
#: bracket of the action-change multiplier searched by :func:`acceleration_matched`
MATCH_BRACKET = (1e-3, 1e4)


def _check_error(error: str) -> str:
    if error not in ERRORS:
        raise ValueError(f"error must be one of {ERRORS}, got {error!r}")
    return error


def yardstick_design(spec: ControlInterface, wind_speed: float, direction: str | float,
                     runnable: bool = False, error: str = "encoder", action_change: float = 1.0,
                     pointing_noise: float | None = None, plants: Any = None) -> LQGDesign:
    """See :func:`_yardstick_design` (cached)."""
    direction = direction if isinstance(direction, str) else float(direction)
    return _yardstick_design(spec, float(wind_speed), direction, bool(runnable), _check_error(error),
                             float(action_change), _check_noise(pointing_noise), plants)


def _check_noise(pointing_noise: float | None) -> float | None:
    if pointing_noise is None:
        return None
    if not (math.isfinite(pointing_noise) and pointing_noise > 0):
        raise ValueError(f"pointing_noise must be None or a positive std (rad), got {pointing_noise!r}")
    return float(pointing_noise)


@lru_cache(maxsize=32)
def _yardstick_design(spec: ControlInterface, wind_speed: float, direction: str | float,
                      runnable: bool = False, error: str = "encoder",
                      action_change: float = 1.0, pointing_noise: float | None = None,
                      plants: Any = None) -> LQGDesign:
    """The full-order H2-optimal design for one scenario wind.

    :param spec: environment interface (period, scales, weight, encoder)
    :param wind_speed: mean wind speed, m/s (> 0)
    :param direction: ``"front"``, ``"side"`` or an angle in rad relative to the dish
    :param runnable: add the command-level disturbance estimate used in simulation
    :param error: ``"encoder"`` (``J_enc``) or ``"pointing"`` (``J_point``)
    :param action_change: multiplier on the environment's action-change weight (1: the
        benchmark's cost; :data:`ERROR_ONLY_WEIGHT`: the error-only limit)
    :param pointing_noise: None: the drive encoders alone; otherwise the yardstick also
        measures the dish's pointing (the monopulse sensor) with white noise of this std per
        step, rad (:func:`dss14_env.baselines.lqg.design_lqg`)
    :param plants: the model the yardstick is optimal for: a
        :class:`~dss14_env.envs.plant.PlantFactory` (its model and wind loads, e.g. a drive
        variant's), None for the shipped model
    """
    if not (math.isfinite(wind_speed) and wind_speed > 0):
        raise ValueError(f"the yardstick needs a positive wind speed (m/s), got {wind_speed!r}")
    if not (math.isfinite(action_change) and action_change > 0):
        raise ValueError(f"the action-change multiplier must be positive, got {action_change!r}")
    direction = direction if isinstance(direction, str) else float(direction_angle(direction))
    dm = build_design_model(spec.dt, order=None, wind=(float(wind_speed), direction),
                            encoder_noise=spec.encoder_noise, bits=spec.encoder_bits, pointing=True,
                            error_output=error, encoders=spec.encoders,
                            model=None if plants is None else plants.model,
                            loads=None if plants is None else plants.loads)
    return design_lqg(dm, spec.weights, w_e=1.0, w_a=action_change, w_i=None,
                      input_noise=REGULARISING_INPUT_NOISE,
                      disturbance_drift=RUNNABLE_DRIFT if runnable else None,
                      rate_limit=spec.rate_limit, pointing_noise=pointing_noise)


def expected_performance(spec: ControlInterface | Any, wind_speed: float, direction: str | float,
                         error: str = "encoder", action_change: float = 1.0,
                         pointing_noise: float | None = None, plants: Any = None) -> dict:
    """See :func:`_expected_performance` (cached per interface, wind, cost, measurement and
    model; a copy is returned).
    """
    spec = as_interface(spec)
    direction = direction if isinstance(direction, str) else float(direction)
    return copy.deepcopy(_expected_performance(spec, float(wind_speed), direction, _check_error(error),
                                               float(action_change), _check_noise(pointing_noise), plants))


@lru_cache(maxsize=256)
def _expected_performance(spec: ControlInterface, wind_speed: float, direction: str | float,
                          error: str = "encoder", action_change: float = 1.0,
                          pointing_noise: float | None = None, plants: Any = None) -> dict:
    """A yardstick's expected 3-sigma errors (mdeg), acceleration and per-step cost.

    :return: dict (JSON-ready): ``error`` (which cost), ``action_change`` (its multiplier),
        ``three_sigma_mdeg`` [az, el] (servo error), ``pointing_three_sigma_mdeg`` [el, xel]
        (pointing error), ``rms_mdeg``, ``pointing_rms_mdeg``, ``accel_three_sigma_deg_s2``
        [az, el] (3σ of the command's change per period over the period) against
        ``accel_limit_deg_s2``, ``cost`` (``J_enc`` per step), ``cost_pointing`` (``J_point``),
        ``cost_riccati`` (the design's own cost from the Riccati solutions), ``n_states`` of the
        plant model and the Riccati residuals; ``pointing_noise`` (rad, or None) the monopulse
        measurement's (:func:`yardstick_design`)
    """
    d = yardstick_design(spec, wind_speed, direction, error=error, action_change=action_change,
                         pointing_noise=pointing_noise, plants=plants)
    perf = stationary_performance(closed_loop(d.dm, lqg_as_linear(d), design_measurement(d)), spec.weights)
    acc = [3.0 * x / spec.dt * R2D for x in perf.pop("command_change_rms_rad_s")]
    perf.update({"error": error, "action_change": float(action_change),
                 "accel_three_sigma_deg_s2": acc, "accel_limit_deg_s2": spec.accel_limit * R2D,
                 "cost_riccati": riccati_cost(d), "n_states": d.dm.n, "n_augmented": d.n_z,
                 "residuals": d.residuals, "wind_speed_mps": float(wind_speed),
                 "pointing_noise_rad": pointing_noise,
                 "direction": direction if isinstance(direction, str) else float(direction)})
    return perf


def pi_performance(spec: ControlInterface | Any, wind_speed: float, direction: str | float,
                   gains: str | tuple = "kp1") -> dict:
    """The sampled PI's expected performance on the yardstick's own model and wind, with the
    statistic of :func:`expected_performance` (stationary whole-record 3σ from the closed loop's
    Lyapunov equation; quantisation as white noise, no limiter): the denominator of a reference
    ratio on one statistic (a yardstick's 3σ / the PI's).

    :param gains: gain-set name or ``(kp, ki)`` (:func:`dss14_env.baselines.analysis.pi_as_linear`)
    :return: the keys of :func:`expected_performance` but the Riccati ones; ``error`` is
        ``"pi"`` and ``action_change`` None
    """
    spec = as_interface(spec)
    dm = yardstick_design(spec, wind_speed, direction, error="pointing").dm
    perf = stationary_performance(closed_loop(dm, pi_as_linear(spec.dt, gains)), spec.weights)
    acc = [3.0 * x / spec.dt * R2D for x in perf.pop("command_change_rms_rad_s")]
    perf.update({"error": "pi", "action_change": None, "accel_three_sigma_deg_s2": acc,
                 "accel_limit_deg_s2": spec.accel_limit * R2D, "n_states": dm.n,
                 "wind_speed_mps": float(wind_speed),
                 "direction": direction if isinstance(direction, str) else float(direction)})
    return perf


def error_only_limit(spec: ControlInterface | Any, wind_speed: float, direction: str | float,
                     error: str = "encoder", plants: Any = None) -> dict:
    """The error-only limit of a yardstick: its expected performance with the action-change
    weight taken to zero (:data:`ERROR_ONLY_WEIGHT`), the smallest 3σ error of its kind that a
    linear controller on the drive encoders reaches on the model, with the acceleration it needs
    (``accel_three_sigma_deg_s2`` against ``accel_limit_deg_s2``).
    """
    return expected_performance(spec, wind_speed, direction, error, ERROR_ONLY_WEIGHT, plants=plants)


def acceleration_matched(spec: ControlInterface | Any, wind_speed: float, direction: str | float,
                         error: str = "encoder", iterations: int = 12,
                         pointing_noise: float | None = None, plants: Any = None) -> dict:
    """The yardstick of ``error``'s kind whose action-change weight makes its largest 3σ
    acceleration (over the axes) equal the command limiter's acceleration limit: the 3σ
    reference of the family of H2-optimal laws that the limit leaves usable (bisection on
    ``log w`` over :data:`MATCH_BRACKET`, ``iterations`` halvings: ~0.7 % in ``w``).

    Within that family nothing has a smaller error at that acceleration; a law outside it
    (another cost shape, a constrained or nonlinear law) may.  Where the benchmark cost's
    yardstick (``w = 1``) already stays within the limit, ``w`` is the bracket's low end or
    the weight where the acceleration reaches it.

    :param pointing_noise: with the monopulse measurement (:func:`yardstick_design`)
    :param plants: on a given model (:func:`yardstick_design`)
    :return: :func:`expected_performance` of the matched design (``action_change`` its ``w``)
    """
    spec = as_interface(spec)
    limit = spec.accel_limit * R2D

    def perf(w: float) -> dict:
        return expected_performance(spec, wind_speed, direction, error, w, pointing_noise, plants)

    lo, hi = (math.log(x) for x in MATCH_BRACKET)
    accel = lambda lw: max(perf(math.exp(lw))["accel_three_sigma_deg_s2"])  # noqa: E731
    if accel(lo) <= limit:
        return perf(MATCH_BRACKET[0])
    for _ in range(int(iterations)):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if accel(mid) > limit else (lo, mid)
    return perf(math.exp(hi))


def references(spec: ControlInterface | Any, wind_speed: float, direction: str | float,
               plants: Any = None) -> dict:
    """The encoder yardstick's :func:`expected_performance` (the keys the runner's
    ``vs_yardstick`` reads) with the pointing yardstick's under ``"pointing"``, on the shipped
    model or ``plants``' (a :class:`~dss14_env.envs.plant.PlantFactory`).
    """
    out = expected_performance(spec, wind_speed, direction, "encoder", plants=plants)
    out["pointing"] = expected_performance(spec, wind_speed, direction, "pointing", plants=plants)
    return out


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
    :param error: ``"encoder"`` (default, ``J_enc``) or ``"pointing"`` (``J_point``)
    :param pointing_noise: None (the drive encoders) or the monopulse measurement's noise std
        per step, rad (:func:`yardstick_design`; the controller's :meth:`measurement` must then
        append the pointing, :class:`dss14_env.baselines.monopulse.MonopulseYardstickController`)
    """

    def __init__(self, env: Any = None, wind_speed: float = 50 * KMH,
                 direction: str | float = "front", name: str = "yardstick", error: str = "encoder",
                 pointing_noise: float | None = None) -> None:
        interface = as_interface(env)
        self.interface = interface
        self.error = _check_error(error)
        self.pointing_noise = _check_noise(pointing_noise)
        self._designs_by_wind: dict[tuple, LQGDesign] = {}
        self._scenarios: list[tuple[float, str | float]] | None = None
        super().__init__(self.design_for(wind_speed, direction), interface, name)

    def design_for(self, speed: float, direction: str | float) -> LQGDesign:
        """The runnable yardstick design for a wind (speed at least 1 m/s; cached)."""
        speed = max(float(speed), 1.0)
        key = (round(speed, 9), direction if isinstance(direction, str) else round(float(direction), 9))
        if key not in self._designs_by_wind:
            self._designs_by_wind[key] = yardstick_design(self.interface, speed, direction, runnable=True,
                                                          error=self.error,
                                                          pointing_noise=self.pointing_noise)
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


class PointingYardstickController(YardstickController):
    """The pointing yardstick as a controller (``yardstick_pointing``): the full-order LQG for
    ``J_point`` and the episode's wind (see :class:`YardstickController`).
    """

    def __init__(self, env: Any = None, wind_speed: float = 50 * KMH, direction: str | float = "front",
                 name: str = "yardstick_pointing", pointing_noise: float | None = None) -> None:
        super().__init__(env, wind_speed, direction, name, error="pointing", pointing_noise=pointing_noise)
