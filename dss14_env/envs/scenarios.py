"""Scenarios and the per-episode draw of the DSS14 environments.

:func:`draw_episode` draws one episode from a ``numpy.random.Generator`` -- the single
environment and every sub-environment of the vector environment call it with their own
generator, in the same order, so both give the same episodes for the same seeds:

1. hydraulic parameters (only with ``randomize_params``; rejection sampling, stable part);
2. mean wind speed (only if ``"random"``: an index into ``wind_speed_grid_kmh``);
3. wind direction (only if ``"random"``: an index into ``wind_direction_grid_deg``);
4. start azimuth, then start elevation (only if ``"random"``: uniform over their ranges);
5. scenario parameters: ``track`` draws rate, amplitude, period and phase (2 each, in that
   order), ``slew`` draws the two signs, ``hold`` and ``step`` draw nothing;
6. the standard normals (one per filter state, 4) of the stationary gust-filter state.

After that the environment draws the encoder noise at t = 0 (with encoder noise), the
monopulse sensor's start (with it) and the episode's first noise block
(:func:`draw_reset`, :func:`draw_noise_block`).

Command trajectories (per axis, relative to the start position, all zero at t = 0)::

    c(t) = v t + A (sin(w t + phi) - sin(phi))      track: sidereal-like rate + slow sinusoid
         + S H(t - t_s)                             step (H: unit step, t_s > 0)
         + s(t - t_0)                               slew: trapezoidal-rate profile, s(T) = D

:func:`command` evaluates ``c`` and ``dc/dt`` for any batch of times and parameter sets.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dss14_env.core.units import DEG, KMH, R2D, WIND_DIRECTIONS
from dss14_env.envs.config import EnvConfig
from dss14_env.envs.plant import Plant, PlantFactory

#: steps per noise block: each episode draws its noise ``NOISE_BLOCK`` steps at a time
NOISE_BLOCK = 256
#: half-width of the start elevation about the model's elevation (``start_el_deg: model``),
#: deg: 29 encoder counts either side, so that the elevation encoder's quantisation phase is
#: drawn, while ``cos(E)`` stays within 2e-4 of the model's
MODEL_EL_SPREAD_DEG = 0.01


# ---------------------------------------------------------------------------- trajectories
def axes_mask(axes: str) -> np.ndarray:
    """``[az, el]`` as 1.0 for the axes an axis selection (``step_axes``, ``slew_axes``:
    ``"az"``, ``"el"``, ``"both"``) moves, 0.0 for the other.
    """
    return np.array([axes in ("az", "both"), axes in ("el", "both")], float)


def trajectory(cfg: EnvConfig, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Command-trajectory parameters of one episode (SI, arrays of shape ``(2,)``: az, el).

    Draws from ``rng`` for ``track`` (rates, amplitudes, periods, phases) and ``slew`` (signs).
    """
    z = np.zeros(2)
    tr = {"v": z.copy(), "amp": z.copy(), "omega": z.copy(), "phase": z.copy(),
          "step": z.copy(), "t_step": np.full(2, math.inf),
          "slew_acc": z.copy(), "slew_t0": z.copy(), "slew_ta": z.copy(), "slew_T": z.copy()}
    s = cfg.scenario
    if s == "track":
        tr["v"] = rng.uniform(-1.0, 1.0, 2) * cfg.track_rate_max_deg_s * DEG
        tr["amp"] = rng.uniform(0.0, 1.0, 2) * cfg.track_amp_max_deg * DEG
        lo, hi = cfg.track_period_range_s
        tr["omega"] = 2.0 * math.pi / rng.uniform(lo, hi, 2)
        tr["phase"] = rng.uniform(0.0, 2.0 * math.pi, 2)
    elif s == "step":
        tr["step"] = axes_mask(cfg.step_axes) * cfg.step_deg * DEG
        tr["t_step"] = np.full(2, cfg.step_time_s)
    elif s == "slew":
        sign = 2.0 * rng.integers(0, 2, 2) - 1.0
        dist = cfg.slew_deg * DEG
        rate, acc = cfg.slew_rate_deg_s * DEG, cfg.slew_accel_deg_s2 * DEG
        ta = rate / acc
        if dist < rate * ta:  # triangular profile: the cruise rate is never reached
            ta = math.sqrt(dist / acc)
            rate = acc * ta
        T = dist / rate + ta if dist > 0 else 0.0
        tr["slew_acc"] = sign * acc * axes_mask(cfg.slew_axes) * (dist > 0)
        tr["slew_t0"] = np.full(2, cfg.slew_time_s)
        tr["slew_ta"] = np.full(2, ta)
        tr["slew_T"] = np.full(2, T)
    tr["sin_phase"] = np.sin(tr["phase"])
    return tr


def command_parts(tr: Mapping[str, np.ndarray]) -> tuple[bool, bool, bool]:
    """Which terms of :func:`command` are non-zero: ``(track, step, slew)``."""
    nz = np.count_nonzero  # a tenth of the time of ndarray.any on a few entries (every reset)
    return nz(tr["v"]) + nz(tr["amp"]) > 0, nz(tr["step"]) > 0, nz(tr["slew_acc"]) > 0


def _per_axis(t: np.ndarray, like: np.ndarray) -> np.ndarray:
    """The times ``t`` once per axis: a new contiguous array of the shape of ``t[..., None]``
    broadcast with ``like`` (an operation of an ``(N, 1)`` with an ``(N, 2)`` array goes pair by
    pair, several times slower than one of two ``(N, 2)`` arrays); ``t[..., None]`` itself where
    the axes are not the last dimension of ``like``.
    """
    shape = np.broadcast(t[..., None], like).shape
    if shape[-1] != 2:  # the axes lie elsewhere: the operations run along the times already
        return t[..., None]
    out = np.empty(shape)
    out[..., 0] = t
    out[..., 1] = t
    return out


def command(tr: Mapping[str, np.ndarray], t: np.ndarray, parts: tuple[bool, bool, bool] | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """Commanded positions and rates relative to the start (rad, rad/s).

    :param tr: trajectory parameters, arrays of shape ``(..., 2)`` (:func:`trajectory`, or a
        stack of them)
    :param t: times, s, shape broadcastable to ``tr``'s leading shape (e.g. ``(B,)`` for one
        parameter set, ``(N,)`` for N stacked sets)
    :param parts: :func:`command_parts` of ``tr`` (computed here if None)
    :return: ``(c, c_dot)``, each of shape ``(..., 2)``

    >>> from dss14_env.envs.config import load_env_config
    >>> cfg = load_env_config(scenario="slew", slew_deg=1.0)
    >>> tr = trajectory(cfg, np.random.default_rng(0))
    >>> c, cd = command(tr, np.array([0.0, 100.0]))
    >>> np.round(np.abs(np.degrees(c[1])), 9).tolist(), np.abs(cd[1]).tolist()
    ([1.0, 1.0], [0.0, 0.0])
    """
    track, step, slew = command_parts(tr) if parts is None else parts
    t = _per_axis(np.asarray(t, float), tr["v"])
    if track:  # c = v t + A (sin(w t + phi) - sin(phi)), c_dot = v + A w cos(w t + phi), in place
        wt = tr["omega"] * t
        wt += tr["phase"]
        c = np.sin(wt)
        c -= tr["sin_phase"]
        c *= tr["amp"]
        c += tr["v"] * t
        cd = np.cos(wt, out=wt)
        cd *= tr["amp"] * tr["omega"]
        cd += tr["v"]
    else:
        c = np.zeros(np.broadcast(t, tr["v"]).shape)  # the shape; np.broadcast_shapes takes 4x as long
        cd = np.zeros_like(c)
    if step:
        c += tr["step"] * (t >= tr["t_step"])
    if slew:
        acc = tr["slew_acc"]
        tau = t - tr["slew_t0"]
        ta, T = tr["slew_ta"], tr["slew_T"]
        r1, r2 = np.maximum(tau, 0.0), np.maximum(tau - ta, 0.0)
        r3, r4 = np.maximum(tau - (T - ta), 0.0), np.maximum(tau - T, 0.0)
        c += 0.5 * acc * (r1 * r1 - r2 * r2 - r3 * r3 + r4 * r4)
        cd += acc * (r1 - r2 - r3 + r4)
    return c, cd


# ---------------------------------------------------------------------------- episodes
@dataclass
class Episode:
    """Everything drawn at a reset (SI).

    :param cfg: the episode's configuration (options applied)
    :param plant: the discretised plant (:class:`dss14_env.envs.plant.Plant`)
    :param wind_speed: mean wind speed, m/s
    :param wind_direction: wind direction relative to the dish, rad (0 front, pi/2 side)
    :param kappa: direction factors of the plant's two gust-filter copies
    :param t_mean: mean wind torques ``[Tw_az, Tw_el]``, N*m
    :param start: absolute start position ``[az, el]``, rad
    :param traj: command-trajectory parameters (:func:`trajectory`)
    :param x0: initial joint plant state (balanced)
    :param r0: rate command holding the initial steady motion, rad/s
    :param params: hydraulic parameters of the plant (empty = nominal)
    :param params_rejected: parameter draws rejected before ``params`` (``randomize_params``),
        by reason (:data:`dss14_env.model.uncertainty.REJECT_REASONS`); empty otherwise
    """

    cfg: EnvConfig
    plant: Plant
    wind_speed: float
    wind_direction: float
    kappa: np.ndarray
    t_mean: np.ndarray
    start: np.ndarray
    traj: dict
    x0: np.ndarray
    r0: np.ndarray
    params: dict
    params_rejected: dict = field(default_factory=dict)


#: the reset-info keys that describe the episode drawn (:func:`episode_info`), beside the
#: first state's (:data:`dss14_env.envs.core.RESET_INFO_KEYS`)
EPISODE_INFO_KEYS = ("scenario", "start_az_deg", "start_el_deg", "params", "params_rejected", "wind_loads")


def episode_info(ep: Episode, wind_loads: str) -> dict[str, Any]:
    """The reset-info entries of one drawn episode (keys :data:`EPISODE_INFO_KEYS`), for both
    environments: scenario, start position (deg), hydraulic parameters (``{}`` = nominal), the
    parameter draws rejected before them, and where the wind loads come from.

    :param wind_loads: the plant factory's ``wind_loads``
    """
    return {"scenario": ep.cfg.scenario, "start_az_deg": float(ep.start[0]) * R2D,
            "start_el_deg": float(ep.start[1]) * R2D, "params": dict(ep.params),
            "params_rejected": dict(ep.params_rejected), "wind_loads": wind_loads}


def draw_episode(cfg: EnvConfig, rng: np.random.Generator, plants: PlantFactory) -> Episode:
    """Draw one episode (see the module docstring for the order of the draws).

    The plant starts in steady motion: the rate loop is in the steady state that moves both
    encoders at the command's initial rate from the start position under the wind torque at
    t = 0 (mean plus the initial gust, held), the gust filter in its stationary distribution,
    and the previous rate command is the one that holds this motion (``r0``).  With a PI
    controller that starts bumplessly from ``r0`` there is no start transient to discard.

    :param cfg: the episode's configuration
    :param rng: the only source of randomness
    :param plants: the factory of the environment's model (plants, parameter draws)
    :raises ValueError: fixed ``params`` outside the model's ranges
    """
    rejected: dict[str, int] = {}
    if cfg.params is not None:
        params = plants.check_params(cfg.params, cfg.source_of("params"))
    elif cfg.randomize_params:
        draw = plants.draw_params(rng)
        params, rejected = draw.values, draw.rejected
    else:
        params = {}
    if cfg.wind_speed_kmh == "random":
        grid = cfg.wind_speed_grid_kmh
        speed = grid[int(rng.integers(len(grid)))] * KMH
    else:
        speed = float(cfg.wind_speed_kmh) * KMH
    wd = cfg.wind_direction
    if wd == "random":
        grid = cfg.wind_direction_grid_deg
        direction = grid[int(rng.integers(len(grid)))] * DEG
    else:
        direction = WIND_DIRECTIONS.get(wd, wd)  # type: ignore[arg-type]
    start = np.empty(2)
    az = cfg.start_az_deg
    start[0] = (rng.uniform(*cfg.start_az_range_deg) if az == "random" else float(az)) * DEG
    start[1] = start_elevation(cfg, rng, plants)
    tr = trajectory(cfg, rng)
    plant = plants.plant(speed, cfg.dt, params, cfg.encoders)  # no draws
    xi = rng.standard_normal(plant.n_wind)
    kappa = plant.kappa(direction)
    t_mean = plant.mean_torque(direction)
    x_wind = plant.filter_state(kappa, xi)
    _, cd0 = command(tr, np.zeros(1))
    x0, r0 = plant.steady_start(x_wind, t_mean, cd0[0])
    return Episode(cfg, plant, speed, float(direction), kappa, t_mean, start, tr, x0, r0, params, rejected)


def draw_reset(cfg: EnvConfig, rng: np.random.Generator, plants: PlantFactory, encoder_sigma: float
               ) -> tuple[Episode, np.ndarray, np.ndarray, np.ndarray]:
    """Every draw of a reset, in their order, for both environments: the episode
    (:func:`draw_episode`), the encoder noise of the reading at t = 0 (rad; zeros without
    noise), with the monopulse sensor (``sensors``) the standard normals of its start
    (:func:`dss14_env.envs.monopulse.sensor_reset`; zeros without it), and the standard normals
    of the first noise block (:func:`draw_noise_block`).

    :param encoder_sigma: encoder noise std, rad
    :return: ``(episode, encoder noise, monopulse start normals, noise block)``
    """
    ep = draw_episode(cfg, rng, plants)
    ne = rng.standard_normal(2) * encoder_sigma if encoder_sigma else np.zeros(2)
    monopulse = "monopulse" in cfg.sensors
    z0 = rng.standard_normal(2) if monopulse else np.zeros(2)
    return ep, ne, z0, draw_noise_block(rng, ep.plant.noise_rank, encoder_sigma > 0.0, monopulse=monopulse)


def start_elevation(cfg: EnvConfig, rng: np.random.Generator, plants: PlantFactory) -> float:
    """The episode's absolute start elevation, rad (one draw, unless fixed).

    ``start_el_deg``: ``"model"`` (the default) the model's elevation -- the structure model's
    ``elevation_angle``, at which its pointing outputs, modes and the cross-elevation scale
    ``cos(E)`` hold -- plus a uniform offset within +-:data:`MODEL_EL_SPREAD_DEG`;
    ``"random"`` uniform over ``start_el_range_deg``; or a fixed angle in deg.

    :raises ValueError: ``"model"`` with the model's elevation outside ``el_limits_deg``
    """
    val = cfg.start_el_deg
    if val == "random":
        return rng.uniform(*cfg.start_el_range_deg) * DEG
    if val != "model":
        return float(val) * DEG
    e = plants.model.cfg.structure.elevation_angle * R2D
    lo, hi = cfg.el_limits_deg
    if not (lo <= e - MODEL_EL_SPREAD_DEG and e + MODEL_EL_SPREAD_DEG <= hi):
        raise ValueError(f"{cfg.source_of('start_el_deg')}: field 'start_el_deg': 'model' starts at the "
                         f"model's elevation {e:g} deg, outside el_limits_deg [{lo:g}, {hi:g}]; set an angle "
                         "or 'random'")
    return (e + rng.uniform(-MODEL_EL_SPREAD_DEG, MODEL_EL_SPREAD_DEG)) * DEG


def block_rows(tr: Mapping[str, np.ndarray], k0: int, dt: float, normals: np.ndarray, encoder_sigma: float,
               parts: tuple[bool, bool, bool] | None = None) -> np.ndarray:
    """The per-step inputs of the steps ``k0 .. k0 + NOISE_BLOCK - 1`` of one episode, as the
    step's loop reads them (:func:`dss14_env.envs.fused.after_product`, N = 1).

    Row ``j`` is the step ``k0 + j``: the command at its end (``t = (k0 + j + 1) dt``, rad), its
    rate (rad/s) and the encoder noise (rad; zeros when there is none).  The single environment
    steps through these rows (the gust noise's standard normals, the first ``k`` columns of
    ``normals``, go into its step block, :func:`dss14_env.envs.plant.step_block`); the vector
    environment evaluates :func:`command` at each step's ``t`` for all its sub-environments with
    the same operations, so they agree exactly.

    :param tr: trajectory parameters, arrays ``(2,)``
    :param k0: first step of the block
    :param dt: control period, s
    :param normals: :func:`draw_noise_block` output ``(NOISE_BLOCK, k [+ 2])`` without the
        monopulse columns (its last two columns are the encoder's, with encoder noise)
    :param encoder_sigma: encoder noise std, rad (0: the normals have no encoder columns)
    :param parts: :func:`command_parts` of ``tr`` (computed here if None)
    :return: ``(3, NOISE_BLOCK, 1, 2)``: ``c``, ``c_dot`` and the noise, ``[az, el]`` per step
    """
    t = np.arange(k0 + 1, k0 + 1 + NOISE_BLOCK) * dt
    # the axes first, so that every operation runs along the block
    c, cd = command({key: v[:, None, None] for key, v in tr.items()}, t, parts)
    rows = np.zeros((3, NOISE_BLOCK, 1, 2))
    rows[0, :, 0] = c[..., 0].T
    rows[1, :, 0] = cd[..., 0].T
    if encoder_sigma:
        np.multiply(normals[:, -2:], encoder_sigma, out=rows[2, :, 0])
    return rows


def draw_noise_block(rng: np.random.Generator, noise_rank: int, encoder_noise: bool,
                     out: np.ndarray | None = None, monopulse: bool = False) -> np.ndarray:
    """Standard normals for the next :data:`NOISE_BLOCK` steps of one episode.

    :param out: a C-contiguous float64 array of the block's shape to draw into (the same
        draws; default: a new array)
    :param monopulse: add the monopulse sensor's two columns (:mod:`dss14_env.envs.monopulse`)
    :return: ``(NOISE_BLOCK, width)``: the gust's ``noise_rank`` columns, then with encoder
        noise the encoders' (az, el), then with the monopulse sensor its (el, xel)
    :raises ValueError: ``out`` of another shape
    """
    shape = (NOISE_BLOCK, noise_width(noise_rank, encoder_noise, monopulse))
    if out is None:
        return rng.standard_normal(shape)
    if out.shape != shape:
        raise ValueError(f"out must have the noise block's shape {shape}, got {out.shape}")
    return rng.standard_normal(out=out)  # without the size argument: a sixth faster, the same draws


def noise_width(noise_rank: int, encoder_noise: bool, monopulse: bool) -> int:
    """Standard normals per step (:func:`draw_noise_block`'s columns)."""
    return noise_rank + (2 if encoder_noise else 0) + (2 if monopulse else 0)
